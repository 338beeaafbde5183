"""A seeded random fault timeline with every kind of fault, for chaos runs (`swarm up --chaos SEED`).

Each kind appears at least once (``accuse`` in swarms of two or more); faults start between 10% and
70% of the run and end by 95% of it (a kill's restart comes 3-15 s after it), so every fault starts
and ends while the swarm runs.
Zones are placed over the square of start pads (``spacing_m`` apart on ceil(sqrt(N)) columns).
"""

from __future__ import annotations

import math

import numpy as np

LINK_KINDS = ("delay", "loss", "duplicate", "reorder")
ZONE_KINDS = ("jam-gnss", "spoof-gnss", "jam-comms")
ALL_KINDS = (*LINK_KINDS, *ZONE_KINDS, "blackout", "kill", "lie", "accuse")


def _link(kind: str, rng: np.random.Generator, vehicles: int) -> dict:
    dst = str(rng.choice(["v*", "gs", f"v{rng.integers(1, vehicles + 1)}"]))
    topic = "mavlink" if dst == "gs" else str(rng.choice(["*", "imu", "odom", "gnss", "ranging", "mavlink"]))
    fault = {"dst": dst, "topic": topic}
    if kind == "delay":
        fault |= {
            "delay_s": round(float(rng.uniform(0.02, 0.3)), 3),
            "jitter_s": round(float(rng.uniform(0, 0.05)), 3),
            "distribution": str(rng.choice(["uniform", "normal", "pareto"])),
        }
    elif kind == "loss":
        fault |= {"percent": round(float(rng.uniform(5, 40)), 1)}
        if rng.random() < 0.5:
            fault["burst"] = round(float(rng.uniform(2, 8)), 1)
    elif kind == "duplicate":
        fault |= {"percent": round(float(rng.uniform(5, 30)), 1)}
    else:
        fault |= {"percent": round(float(rng.uniform(5, 30)), 1), "gap_s": round(float(rng.uniform(0.02, 0.2)), 3)}
    return fault


def _fault(kind: str, rng: np.random.Generator, vehicles: int, extent_m: float) -> dict:
    if kind in LINK_KINDS:
        return _link(kind, rng, vehicles)
    if kind in ZONE_KINDS:
        fault = {
            "center_m": [round(float(c), 1) for c in rng.uniform(0, extent_m, 2)],
            "radius_m": round(float(rng.uniform(20, 50)), 1),
        }
        if kind == "spoof-gnss":
            fault |= {
                "drift_mps": round(float(rng.uniform(0.2, 1.0)), 2),
                "heading_deg": round(float(rng.uniform(0, 360)), 1),
            }
        return fault
    vehicle = int(rng.integers(1, vehicles + 1))
    if kind == "blackout":
        return {"vehicle": vehicle, "sensor": str(rng.choice(["imu", "odom", "gnss", "ranging"]))}
    if kind == "accuse":
        others = [v for v in range(1, vehicles + 1) if v != vehicle]
        names = rng.choice(others, size=min(len(others), int(rng.integers(1, 4))), replace=False)
        return {"vehicle": vehicle, "names": sorted(int(n) for n in names)}
    if kind == "lie":
        return {
            "vehicle": vehicle,
            "offset_m": [round(float(c), 1) for c in rng.uniform(-30, 30, 2)],
            "drift_mps": round(float(rng.uniform(0, 0.3)), 2),
            "cov_scale": round(float(rng.choice([0.01, 0.1, 1.0])), 2),
        }
    return {"vehicle": vehicle, "restart_after_s": round(float(rng.uniform(3, 15)), 1)}


def chaos_faults(seed: int, *, vehicles: int, duration_s: float, spacing_m: float, extra: int = 6) -> list[dict]:
    """Every kind once plus ``extra`` random ones, each with a start and duration inside the run."""
    rng = np.random.default_rng([seed, 0xC4A05])
    possible = [k for k in ALL_KINDS if k != "accuse" or vehicles > 1]  # one vehicle has nobody to accuse
    kinds = possible + [str(k) for k in rng.choice([k for k in possible if k != "kill"], extra)]
    extent_m = (math.ceil(math.sqrt(vehicles)) - 1) * spacing_m + 1.0
    faults = []
    for n, kind in enumerate(kinds, start=1):
        fault = {"kind": kind, "name": f"chaos-{n}-{kind}", **_fault(kind, rng, vehicles, extent_m)}
        start = float(rng.uniform(0.1, 0.7))
        fault["start_s"] = round(start * duration_s, 2)
        if kind != "kill":  # every fault ends inside the run (by 95% of it)
            fault["for_s"] = round(float(rng.uniform(0.05, min(0.25, 0.95 - start))) * duration_s, 2)
        faults.append(fault)
    return faults
