"""``computed_once``: ``functools.cached_property`` without the lock that Python 3.11 takes on each
first read (a lock per property, taken once per object: on the hot path a fix or a score pays it
for every property it has; Python 3.12 dropped the lock). The value is worked out from the
object on its first read and kept in its ``__dict__`` (a frozen dataclass's too), where later reads
find it first. Two threads reading a new object at once may both work it out: it must depend on
nothing but the object."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Generic, TypeVar

T = TypeVar("T")


class computed_once(Generic[T]):  # noqa: N801 (a decorator, named like the one it stands in for)
    def __init__(self, func: Callable[[Any], T]) -> None:
        self.func, self.name, self.__doc__ = func, func.__name__, func.__doc__

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name

    def __get__(self, obj: Any, owner: type | None = None) -> Any:
        if obj is None:
            return self
        value = obj.__dict__[self.name] = self.func(obj)
        return value


def known(obj: Any, **values: Any) -> None:
    """Keep ``values`` as ``obj``'s computed_once properties of those names, as if they had been read:
    for a caller that works them out for many objects at once. Each must be what the property
    would give."""
    obj.__dict__.update(values)
