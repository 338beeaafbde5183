"""The run's clock (part of bus.config's swarm configuration): lockstep or realtime, its speed and
tick, the run's length, the timeouts the world and the ground station wait for each other with, and
how the processes off lockstep's critical path yield the cores."""

from __future__ import annotations

from enum import StrEnum

from pydantic import Field, model_validator

from bus.strict_model import Strict

LOCKSTEP_RESTART_TICK_S = 0.5  # lockstep's tick under `swarm up --restart on-failure` (cli.main)


class ClockMode(StrEnum):
    """How the world's clock advances: ``LOCKSTEP``, tick k only after every live vehicle acknowledged
    tick k-1 (reproducible bit for bit, as fast as the processes go); ``REALTIME``, with the wall clock
    times the speed factor."""

    LOCKSTEP = "lockstep"
    REALTIME = "realtime"


class ClockConfig(Strict):
    mode: ClockMode = ClockMode.LOCKSTEP
    speed: float = Field(1.0, gt=0, le=1000, description="realtime: sim seconds per wall second")
    tick_s: float | None = Field(
        None,
        gt=0,
        le=1.0,
        description="sim time per clock tick (lockstep barrier): default 0.02 in realtime; in lockstep 1, or 0.5 "
        "with cameras, a live view, kill faults or a truth batch too large for 1 s",
    )
    duration_s: float = Field(60.0, gt=0, le=86400)
    ack_timeout_s: float = Field(
        10.0, gt=0, description="lockstep (realtime: the first tick): wall time before a silent vehicle is dead"
    )
    start_timeout_s: float = Field(
        60.0,
        gt=0,
        description="wall time to wait for the next process to join (the start goes on while processes keep joining)",
    )
    gone_timeout_s: float = Field(
        30.0,
        gt=0,
        description="wall time the world and the ground station wait for "
        "each other after one disappears, before ending the run",
    )
    gs_lag_ticks: int = Field(
        1,
        ge=1,
        le=10_000,
        description="lockstep: how many ticks the ground station may lag "
        "(what a ground-station crash can lose: up to 1 s of scoring at the default tick)",
    )
    background_niceness: int = Field(
        19,
        ge=0,
        le=19,
        description="lockstep: the niceness the world and the ground station run at, so that the vehicles' "
        "cycles, the barrier's critical path, get the cores first (0: the default priority)",
    )

    @model_validator(mode="after")
    def _default_tick(self) -> ClockConfig:
        """Realtime's default tick; lockstep's depends on the rest of the run (SwarmConfig)."""
        if self.tick_s is None and self.mode is ClockMode.REALTIME:
            object.__setattr__(self, "tick_s", 0.02)
        return self
