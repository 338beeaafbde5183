"""Vehicle ids claimed from the swarm at start-up (`swarm vehicle --id auto`, as compose replicas do).

The ground station answers claims on ``<prefix>/ctl/claim`` one at a time, so two vehicles can never
get the same id, even when they start together. A host (container) that claims again, after a
restart, gets its old id back and learns how often it was started before (its reset_counter); an id
whose vehicle is alive is never handed out twice. In a secure swarm the reply carries the vehicle's
own login and signing key; the claimer logged in as ``enroll``, which may do nothing else.
"""

from __future__ import annotations

from pydantic import Field

from bus.plan import _Message

HOST_PATTERN = r"^[A-Za-z0-9_.:\-]{1,128}$"


class ClaimRequest(_Message):
    host: str = Field(pattern=HOST_PATTERN, description="a name unique to the claiming process's host or container")


class ClaimReply(_Message):
    """The id, how often this host claimed before, and (secure swarms) the vehicle's own zenoh
    password and MAVLink signing key (64 hex characters): all a vehicle needs to speak as itself."""

    ok: bool
    vehicle_id: int = Field(0, ge=0, le=250)
    restarts: int = Field(0, ge=0, le=2**31)
    error: str = Field("", max_length=500)
    zenoh_password: str = Field("", max_length=128)
    signing_key: str = Field("", pattern=r"^([0-9a-f]{64})?$")
