"""What a vehicle says in a STATUSTEXT (at most 50 characters) that the ground station makes an event
of: each kind typed here, its text written by ``text_of`` on the vehicle and read back by ``read`` at
the ground station, so the two cannot drift apart. ``read`` is total: any text gives a notice or None.

- ``EstimatorReset``: the filter fell back or started over (event ``estimator_reset``);
- ``Verdict``: the vehicle's neighbour monitor trusts or distrusts a neighbour again
  (``neighbour_trusted`` / ``neighbour_distrusted``);
- ``Contradicted``: an accusation the vehicle's own evidence contradicts (``accusation_contradicted``).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any

MAX_TEXT = 50  # STATUSTEXT's text field


@dataclass(frozen=True)
class EstimatorReset:
    cause: str


@dataclass(frozen=True)
class Verdict:
    neighbour: int
    trusted: bool
    reason: str


@dataclass(frozen=True)
class Contradicted:
    accuser: int
    accused: int


Said = EstimatorReset | Verdict | Contradicted
RESET_PREFIX = "estimator reset"
_VERDICT = re.compile(r"(distrust|trust) v([1-9][0-9]{0,2}): (.{0,60})")
_CONTRADICTED = re.compile(r"discredit v([1-9][0-9]{0,2}): accuses v([1-9][0-9]{0,2}), .{0,40}")


def text_of(said: Said) -> str:
    """The STATUSTEXT a vehicle sends for ``said`` (cut at MAX_TEXT characters on the wire)."""
    if isinstance(said, EstimatorReset):
        return f"{RESET_PREFIX}: {said.cause}"
    if isinstance(said, Verdict):
        return f"{'trust' if said.trusted else 'distrust'} v{said.neighbour}: {said.reason}"
    return f"discredit v{said.accuser}: accuses v{said.accused}, consistent here"


def read(text: Any) -> Said | None:
    """The notice a STATUSTEXT says, None for any other text or value (total)."""
    if not isinstance(text, str):
        return None
    if text.startswith(RESET_PREFIX):
        return EstimatorReset(text.removeprefix(RESET_PREFIX).removeprefix(": "))
    if (match := _VERDICT.fullmatch(text)) is not None:
        return Verdict(int(match.group(2)), match.group(1) == "trust", match.group(3))
    if (match := _CONTRADICTED.fullmatch(text)) is not None:
        return Contradicted(int(match.group(1)), int(match.group(2)))
    return None


def event_of(said: Said, text: str) -> tuple[str, dict[str, object]]:
    """The ground station's event for a notice (its kind and its fields besides the vehicle)."""
    if isinstance(said, EstimatorReset):
        return "estimator_reset", {"text": text}
    if isinstance(said, Verdict):
        kind = "neighbour_trusted" if said.trusted else "neighbour_distrusted"
        return kind, {"neighbour": said.neighbour, "reason": said.reason}
    return "accusation_contradicted", {"accuser": said.accuser, "accused": said.accused}
