"""How a vehicle filter fuses a GNSS fix: observed through its GNSS model, its noise the white part of
what the receiver reports (or IAE's, vehicle.estimators.adaptive), judged by the GNSS health monitor
(vehicle.estimators.gnss_health) before it is fused; a position reset the monitor asks for is first put to the
believed neighbours (``may_reset``: vehicle.estimators.trust). Pure."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from bus import messages as m
from bus.topics import Topic
from vehicle.estimators.parts import GnssObservation, Store
from vehicle.estimators.state import FilterState, tally_nis

MayReset = Callable[[np.ndarray], bool]  # whether a reset by this offset (2,) m is allowed
Reset = Callable[[np.ndarray, float], None]  # jump the position by an offset (2,) m with a per-axis variance m^2


def fuse_gnss(
    s: FilterState,
    store: Store,
    gnss: GnssObservation,
    fix: m.GnssFix,
    gate: float,
    *,
    may_reset: MayReset | None,
    reset: Reset,
) -> None:
    """Fuse ``fix`` into ``s`` (already propagated to its stamp) if the GNSS health monitor trusts the
    receiver and the fix passes its tests; counts it accepted or rejected."""
    observed = gnss.observe(s.x, fix.covariance_m2)
    H = observed.full_H(len(s.x))
    y, HPH = fix.position_m - observed.predicted, H @ s.P @ H.T
    # the fix's noise from here on: the white part of what it reports, or IAE's
    R = observed.R if s.iae is None else s.iae.adapt(Topic.GNSS, y, HPH, observed.R)
    verdict = s.gnss_health.check(fix.stamp_us, y, HPH + R, R, may_reset)
    if verdict.reset_offset_m is not None:
        reset(verdict.reset_offset_m, verdict.reset_variance_m2)
    if not verdict.fuse:
        s.counters.gnss_rejected += 1
        return
    observed = gnss.observe(s.x, R)  # the position may have been reset
    y = fix.position_m - observed.predicted
    tally_nis(s, "gnss", store.update(s, y, observed.H, R, gate, observed.idx), len(y))
    s.counters.gnss_accepted += 1
