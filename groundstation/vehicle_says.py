"""What a vehicle's STATUSTEXT announces: the events the ground station logs for it (a reset, a
trust verdict on a neighbour, an accusation its own evidence contradicted), read by bus.notices, the
module the vehicle writes them with. Pure and total: any text gives a list, empty for plain messages."""

from __future__ import annotations

from bus import notices


def announced(text: object) -> list[tuple[str, dict[str, object]]]:
    """(event kind, its fields besides the vehicle) for each event ``text`` announces."""
    said = notices.read(text)
    return [] if said is None else [notices.event_of(said, str(text))]
