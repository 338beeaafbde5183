"""`swarm fault add`'s flags, derived from the fault kinds' registry (bus.faults): each field a kind
declares with ``cli(flag, read, example)`` is a flag, its text read by its reader, its help naming the
kinds that take it. A new kind's fields become flags with no edit here."""

from __future__ import annotations

import inspect
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import typer

from bus.errors import ConfigError
from bus.faults import BY_KIND, FaultBase
from cli.quantities import centre, metres, percent, seconds, vehicle_number, vehicle_numbers

BASE_FIELDS = tuple(FaultBase.model_fields)  # name, start_s, for_s: every kind's, listed last


@dataclass
class Flag:
    """One flag of `swarm fault add`: the field it sets, how its text is read, the kinds that take it."""

    flag: str
    field_name: str
    read: str
    example: str
    description: str
    kinds: list[str] = field(default_factory=list)

    @property
    def param(self) -> str:
        """The Python name typer hands the flag's value under."""
        name = self.flag.removeprefix("--").replace("-", "_")
        return name + "_" if name in ("in", "for", "from") else name

    def help(self) -> str:
        who = "every kind" if self.field_name in BASE_FIELDS else ", ".join(self.kinds)
        words = f"{who}: {self.description}" if self.description else who
        words = words.replace("[", "\\[")  # rich would read [x, y] as markup
        return f"{words} (e.g. {self.example})" if self.example else words

    def value(self, text: str) -> Any:
        """The field's value from the flag's text; ConfigError naming the flag when it cannot be read."""
        readers: dict[str, Callable[[str], Any]] = {
            "text": str,
            "float": lambda t: _number(t, self.flag),
            "seconds": lambda t: seconds(t, self.flag),
            "metres": lambda t: metres(t, self.flag),
            "percent": percent,
            "xy": lambda t: centre(t, self.flag),
            "vehicle": vehicle_number,
            "vehicles": lambda t: vehicle_numbers(t, self.flag),
        }
        return readers[self.read](text)


def _number(text: str, flag: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise ConfigError(f"{flag}: not a number: {text!r}") from None


def addable_kinds() -> list[str]:
    """The kinds `swarm fault add` adds (a kill has its own command: `swarm fault kill`)."""
    return [name for name, kind in BY_KIND.items() if kind.applied_by != "supervisor"]


def flags(kinds: list[str] | None = None) -> dict[str, Flag]:
    """Every flag of the ``kinds`` (all of the registry's by default) by field name, kinds' own fields
    first, then the base fields; a flag shared by kinds means the same field, read the same way."""
    out: dict[str, Flag] = {}
    for name in kinds if kinds is not None else list(BY_KIND):
        for field_name, info in BY_KIND[name].model_fields.items():
            extra = info.json_schema_extra if isinstance(info.json_schema_extra, dict) else None
            if extra is None or "flag" not in extra:
                continue
            known = out.setdefault(
                field_name,
                Flag(str(extra["flag"]), field_name, str(extra["read"]), str(extra["example"]), info.description or ""),
            )
            assert (known.flag, known.read) == (extra["flag"], extra["read"]), (name, field_name)
            if field_name not in BASE_FIELDS:
                known.kinds.append(name)
    return {k: v for k, v in out.items() if k not in BASE_FIELDS} | {k: out[k] for k in BASE_FIELDS if k in out}


def with_flag_options(
    function: Callable[..., None], all_flags: dict[str, Flag], rest: list[inspect.Parameter]
) -> Callable[..., None]:
    """``function(**values)`` given the signature typer reads: a ``kind`` argument, one optional text
    option per flag, then ``rest``."""
    keyword = inspect.Parameter.KEYWORD_ONLY
    kind = typer.Argument(..., help=f"one of: {', '.join(addable_kinds())}")
    parameters = [inspect.Parameter("kind", keyword, default=kind, annotation=str)]
    for flag in all_flags.values():
        option = typer.Option(None, flag.flag, help=flag.help())
        parameters.append(inspect.Parameter(flag.param, keyword, default=option, annotation=str | None))
    parameters += rest
    function.__signature__ = inspect.Signature(parameters)  # type: ignore[attr-defined]
    function.__annotations__ = {p.name: p.annotation for p in parameters}
    return function
