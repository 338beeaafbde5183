"""One base exception for swarmloc, with a subclass per concern (the evo pattern)."""


class SwarmlocError(Exception):
    """Base of every error swarmloc raises on purpose; the CLI maps it to exit status 1."""


class DecodeError(SwarmlocError):
    """A payload that crossed the bus is malformed: wrong type, shape, range or encoding."""


class AccessDenied(SwarmlocError):
    """A process asked the bus for something its role may not do (e.g. a vehicle reading truth)."""


class ConfigError(SwarmlocError):
    """A configuration value or command-line argument is invalid."""


class BusUnavailable(SwarmlocError):
    """The zenoh session could not be opened: no router answers, or the login or TLS was refused."""


class MavlinkRejected(DecodeError):
    """A well-formed MAVLink frame that failed authentication or the content checks; ``reason`` is one
    of bus.rejections.REASONS (unsigned, bad_signature, replay, stale_stream, future_timestamp,
    unknown_sysid, degenerate)."""

    def __init__(self, reason: str, detail: str) -> None:
        super().__init__(f"MAVLink frame rejected ({reason}): {detail}")
        self.reason = reason
