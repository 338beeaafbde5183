"""Field specifications and the strict msgpack codec behind every sensor message.

A message is a frozen dataclass whose fields are ``Annotated[type, spec]``. ``encode`` packs it as a
msgpack map ``{"type": name, "v": version, <field>: value, ...}``; numpy arrays travel as
``{"dtype": "<f8", "shape": [...], "data": raw bytes}``. ``decode`` checks everything and raises
:class:`bus.errors.DecodeError` (and nothing else) on any malformed payload.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import struct
from typing import Any, Protocol, TypeVar, get_type_hints

import msgpack
import numpy as np

from bus.errors import DecodeError
from bus.spd import spd_values

WIRE_VERSION = 1
MAX_PAYLOAD_BYTES = 1 << 20
T = TypeVar("T")


class FieldSpec(Protocol):
    def pack(self, value: Any) -> Any: ...
    def unpack(self, name: str, raw: Any) -> Any: ...


@dataclasses.dataclass(frozen=True)
class Int:
    lo: int
    hi: int

    def pack(self, value: Any) -> int:
        return int(value)

    def unpack(self, name: str, raw: Any) -> int:
        if isinstance(raw, bool) or not isinstance(raw, int):
            raise DecodeError(f"{name}: expected an integer, got {type(raw).__name__}")
        if not self.lo <= raw <= self.hi:
            raise DecodeError(f"{name}: {raw} outside [{self.lo}, {self.hi}]")
        return raw


@dataclasses.dataclass(frozen=True)
class Float:
    max_abs: float

    def pack(self, value: Any) -> float:
        return float(value)

    def unpack(self, name: str, raw: Any) -> float:
        if isinstance(raw, bool) or not isinstance(raw, (int, float)):
            raise DecodeError(f"{name}: expected a number, got {type(raw).__name__}")
        value = float(raw)
        if not math.isfinite(value) or abs(value) > self.max_abs:
            raise DecodeError(f"{name}: {value!r} is not finite or exceeds {self.max_abs:g}")
        return value


@dataclasses.dataclass(frozen=True)
class Counts:
    """A tuple of at most ``max_len`` integers in [0, hi] (travels as a msgpack list)."""

    max_len: int
    hi: int = 2**53

    def pack(self, value: Any) -> list[int]:
        return [int(v) for v in value]

    def unpack(self, name: str, raw: Any) -> tuple[int, ...]:
        if not isinstance(raw, list) or len(raw) > self.max_len:
            raise DecodeError(f"{name}: expected a list of at most {self.max_len} integers")
        # type() is int: no bool (msgpack gives plain ints); min and max in C instead of a test per entry
        if raw and not (set(map(type, raw)) == {int} and min(raw) >= 0 and max(raw) <= self.hi):
            raise DecodeError(f"{name}: entries must be integers in [0, {self.hi}]")
        return tuple(raw)


@dataclasses.dataclass(frozen=True)
class Floats:
    """A tuple of finite floats within +-``max_abs`` whose length is one of ``lengths`` (travels as a
    msgpack list)."""

    lengths: tuple[int, ...]
    max_abs: float

    def pack(self, value: Any) -> list[float]:
        return [float(v) for v in value]

    def unpack(self, name: str, raw: Any) -> tuple[float, ...]:
        if not isinstance(raw, list) or len(raw) not in self.lengths:
            raise DecodeError(f"{name}: expected a list of {' or '.join(map(str, self.lengths))} numbers")
        if not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and abs(v) <= self.max_abs  # NaN fails too
            for v in raw
        ):
            raise DecodeError(f"{name}: entries must be finite numbers within +-{self.max_abs:g}")
        return tuple(float(v) for v in raw)


@dataclasses.dataclass(frozen=True)
class Text:
    """A short printable string (travels as a msgpack str)."""

    max_len: int

    def pack(self, value: Any) -> str:
        return str(value)

    def unpack(self, name: str, raw: Any) -> str:
        if not isinstance(raw, str) or len(raw) > self.max_len or not raw.isprintable():
            raise DecodeError(f"{name}: expected printable text of at most {self.max_len} characters")
        return raw


@dataclasses.dataclass(frozen=True)
class Bool:
    def pack(self, value: Any) -> bool:
        return bool(value)

    def unpack(self, name: str, raw: Any) -> bool:
        if not isinstance(raw, bool):
            raise DecodeError(f"{name}: expected a boolean, got {type(raw).__name__}")
        return raw


@dataclasses.dataclass(frozen=True)
class Array:
    """A float64 array of fixed ``shape`` with finite entries bounded by ``max_abs``."""

    shape: tuple[int, ...]
    max_abs: float

    def pack(self, value: Any) -> dict[str, Any]:
        arr = np.ascontiguousarray(value, dtype="<f8")
        if arr.shape != self.shape:
            raise ValueError(f"expected shape {self.shape}, got {arr.shape}")
        return {"dtype": "<f8", "shape": list(arr.shape), "data": arr.tobytes()}

    def unpack(self, name: str, raw: Any) -> np.ndarray:
        return np.array(self.unpack_values(name, raw), dtype=np.float64).reshape(self.shape)

    def unpack_values(self, name: str, raw: Any) -> tuple[float, ...]:
        """Validated entries in row-major order (plain floats: faster than numpy for tiny arrays)."""
        if not isinstance(raw, dict) or raw.keys() != {"dtype", "shape", "data"}:
            raise DecodeError(f"{name}: expected an array map with dtype, shape and data")
        if raw["dtype"] != "<f8":
            raise DecodeError(f"{name}: dtype must be '<f8', got {raw['dtype']!r}")
        if not isinstance(raw["shape"], list) or tuple(raw["shape"]) != self.shape:
            raise DecodeError(f"{name}: shape must be {list(self.shape)}, got {raw['shape']!r}")
        data, count = raw["data"], math.prod(self.shape)
        if not isinstance(data, bytes) or len(data) != 8 * count:
            raise DecodeError(f"{name}: data must be {8 * count} raw bytes")
        values = struct.unpack(f"<{count}d", data)
        if not all(abs(v) <= self.max_abs for v in values):  # also rejects NaN and inf
            raise DecodeError(f"{name}: entries must be finite and within +-{self.max_abs:g}")
        return values


@dataclasses.dataclass(frozen=True)
class Covariance(Array):
    """A symmetric positive-definite ``n x n`` float64 matrix."""

    def unpack(self, name: str, raw: Any) -> np.ndarray:
        values = self.unpack_values(name, raw)
        n = self.shape[0]
        for i in range(n):
            for j in range(i + 1, n):
                a, b = values[i * n + j], values[j * n + i]
                if abs(a - b) > 1e-9 * max(abs(a), abs(b), 1e-300):
                    raise DecodeError(f"{name}: covariance is not symmetric")
        if not spd_values(values, n):
            raise DecodeError(f"{name}: covariance is not positive definite")
        return np.array(values, dtype=np.float64).reshape(self.shape)


@functools.cache
def _specs(cls: type) -> tuple[tuple[str, FieldSpec], ...]:
    hints = get_type_hints(cls, include_extras=True)
    specs = []
    for field in dataclasses.fields(cls):
        metadata = getattr(hints[field.name], "__metadata__", ())
        if not metadata:
            raise TypeError(f"{cls.__name__}.{field.name} has no field spec")
        specs.append((field.name, metadata[0]))
    return tuple(specs)


def encode(message: Any) -> bytes:
    """Pack a message dataclass into msgpack bytes."""
    cls = type(message)
    body: dict[str, Any] = {"type": cls.__name__, "v": WIRE_VERSION}
    for name, spec in _specs(cls):
        body[name] = spec.pack(getattr(message, name))
    return msgpack.packb(body, use_bin_type=True)


def decode(cls: type[T], payload: bytes) -> T:
    """Unpack and validate ``payload`` as a ``cls`` message; raise DecodeError if it is not one."""
    body = unpack_tagged(payload, cls.__name__)
    specs = _specs(cls)
    expected = {name for name, _ in specs} | {"type", "v"}
    if set(body) != expected:
        missing, extra = sorted(expected - set(body)), sorted(map(str, set(body) - expected))
        raise DecodeError(f"{cls.__name__}: missing fields {missing}, unexpected fields {extra}")
    return cls(**{name: spec.unpack(f"{cls.__name__}.{name}", body[name]) for name, spec in specs})


def unpack_tagged(payload: bytes, type_name: str, max_bytes: int = MAX_PAYLOAD_BYTES) -> dict:
    """The msgpack map of a payload tagged ``{"type": type_name, "v": WIRE_VERSION, ...}`` (columnar
    formats and, through decode, the dataclass codec); DecodeError for anything else."""
    if not isinstance(payload, (bytes, bytearray, memoryview)):
        raise DecodeError(f"{type_name}: payload must be bytes, got {type(payload).__name__}")
    if len(payload) > max_bytes:
        raise DecodeError(f"{type_name}: payload of {len(payload)} bytes exceeds {max_bytes}")
    try:
        body = msgpack.unpackb(payload, raw=False, strict_map_key=True, use_list=True)
    except Exception as exc:  # msgpack raises many types on garbage; all mean the same here
        raise DecodeError(f"{type_name}: not valid msgpack ({type(exc).__name__})") from None
    if not isinstance(body, dict):
        raise DecodeError(f"{type_name}: expected a map, got {type(body).__name__}")
    if body.get("type") != type_name or body.get("v") != WIRE_VERSION:
        raise DecodeError(f"{type_name}: wrong type tag or version ({body.get('type')!r}, {body.get('v')!r})")
    return body
