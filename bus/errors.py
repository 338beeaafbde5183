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
