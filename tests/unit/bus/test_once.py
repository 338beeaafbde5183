"""bus.once.computed_once: worked out on the first read only, kept on the object (frozen too)."""

from dataclasses import dataclass

from bus.once import computed_once


@dataclass(frozen=True)
class _Point:
    x: float
    y: float
    calls: list

    @computed_once
    def norm(self) -> float:
        """|(x, y)|"""
        self.calls.append(1)
        return (self.x**2 + self.y**2) ** 0.5


def test_a_value_is_worked_out_once_per_object_and_kept_on_it():
    calls: list = []
    p, q = _Point(3.0, 4.0, calls), _Point(6.0, 8.0, calls)
    assert (p.norm, p.norm, q.norm, q.norm) == (5.0, 5.0, 10.0, 10.0)
    assert len(calls) == 2
    assert vars(p)["norm"] == 5.0


def test_the_class_shows_the_descriptor_with_its_docstring():
    assert isinstance(_Point.norm, computed_once)
    assert _Point.norm.__doc__ == "|(x, y)|"
