"""What crosses the bus about faults: the plan the ground station publishes, and the requests and
replies of ``swarm fault ...`` (JSON, validated by pydantic; anything malformed is a DecodeError)."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from bus.errors import DecodeError
from bus.faults import Fault

MAX_PLAN_BYTES = 1 << 20


class _Message(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class FaultPlan(_Message):
    """The whole plan; ``version`` grows with every change, so receivers keep the newest."""

    version: int = Field(ge=0, le=2**53)
    faults: tuple[Fault, ...] = ()


class FaultRequest(_Message):
    """``add`` (``fault``; with ``relative`` its start_s counts from the swarm's current sim time),
    ``remove`` (``name``), ``clear`` or ``list``."""

    op: Literal["add", "remove", "clear", "list"]
    fault: Fault | None = None
    name: str | None = Field(None, max_length=64)
    relative: bool = True


class FaultState(_Message):
    name: str
    kind: str
    state: Literal["pending", "active", "expired"]
    description: str


class FaultReply(_Message):
    ok: bool
    error: str = ""
    sim_time_s: float = 0.0
    plan: FaultPlan
    states: tuple[FaultState, ...] = ()


def encode_json(message: _Message) -> bytes:
    return message.model_dump_json().encode()


def decode_json(cls: type[_Message], payload: bytes) -> _Message:
    """Validate ``payload`` as ``cls``; DecodeError names the first problem."""
    if not isinstance(payload, (bytes, bytearray, memoryview)):
        raise DecodeError(f"{cls.__name__}: payload must be bytes, got {type(payload).__name__}")
    if len(payload) > MAX_PLAN_BYTES:
        raise DecodeError(f"{cls.__name__}: payload of {len(payload)} bytes exceeds {MAX_PLAN_BYTES}")
    try:
        return cls.model_validate_json(bytes(payload))
    except ValidationError as exc:
        first = exc.errors()[0]
        where = ".".join(str(p) for p in first["loc"]) or cls.__name__
        raise DecodeError(f"{cls.__name__}: {where}: {first['msg']}") from None
