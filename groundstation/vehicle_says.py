"""What a vehicle's STATUSTEXT announces: the events the ground station logs for it (a reset, a
trust verdict on a neighbour, an accusation its own evidence contradicted). Pure and total: any text
gives a list, empty for plain messages."""

from __future__ import annotations

import re

_VERDICT = re.compile(r"(distrust|trust) v([1-9][0-9]{0,2}): (.{0,60})")
_CONTRADICTION = re.compile(r"discredit v([1-9][0-9]{0,2}): accuses v([1-9][0-9]{0,2}), .{0,40}")


def trust_verdict(text: str) -> tuple[str, int, str] | None:
    """("neighbour_distrusted" | "neighbour_trusted", neighbour, reason) from a vehicle's STATUSTEXT
    (vehicle.estimators.filter says "distrust v3: <reason>"), None for any other text (total)."""
    match = _VERDICT.fullmatch(text) if isinstance(text, str) else None
    if match is None:
        return None
    kind = "neighbour_distrusted" if match.group(1) == "distrust" else "neighbour_trusted"
    return kind, int(match.group(2)), match.group(3)


def contradiction(text: str) -> tuple[int, int] | None:
    """(accuser, accused) from a vehicle's STATUSTEXT saying its own evidence contradicted an
    accusation (vehicle.estimators.trust says "discredit v4: accuses v1, consistent here"), None
    for any other text (total)."""
    match = _CONTRADICTION.fullmatch(text) if isinstance(text, str) else None
    return None if match is None else (int(match.group(1)), int(match.group(2)))


def announced(text: str) -> list[tuple[str, dict[str, object]]]:
    """(event kind, its fields besides the vehicle) for each event ``text`` announces."""
    out: list[tuple[str, dict[str, object]]] = []
    if isinstance(text, str) and text.startswith("estimator reset"):
        out.append(("estimator_reset", {"text": text}))
    verdict = trust_verdict(text)
    if verdict is not None:
        kind, neighbour, reason = verdict
        out.append((kind, {"neighbour": neighbour, "reason": reason}))
    contradicted = contradiction(text)
    if contradicted is not None:
        out.append(("accusation_contradicted", {"accuser": contradicted[0], "accused": contradicted[1]}))
    return out
