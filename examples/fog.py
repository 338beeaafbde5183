"""Adding a fault kind, shown to work: ``frames_in_fog`` flies one camera vehicle around its circle
through a fog bank (the ``fog`` kind, bus/faults/fog.py) and counts the camera frames the world makes
with and without it (docs/tutorial/adding-a-fault-kind.md; the tests run it). Pure: the world in this
process, no bus."""

from __future__ import annotations

import numpy as np

from bus.config import build_config
from bus.topics import Topic
from launch.in_process import samples
from sim.world import World

FOG = {"kind": "fog", "center_m": [20.0, 0.0], "radius_m": 10.0}  # over the east side of the circle


def frames_in_fog(*, seed: int = 1, duration_s: float = 40.0) -> dict[str, int]:
    """Camera frames of one vehicle circling (radius 20 m around the origin) through ``FOG``: how many
    the world makes in clear air, how many with the fog, and how many of those it still made while the
    vehicle was inside the fog bank (none, if the fault works)."""
    counts = {}
    for label, faults in (("clear", []), ("fog", [FOG])):
        config = build_config(
            {
                "world": {"vehicles": 1, "seed": seed, "trajectories": ["circle"]},
                "clock": {"duration_s": duration_s},
                "sensors": {"camera_rate_hz": 5},
                "faults": faults,
            }
        )
        end_us = round(duration_s * 1e6)
        out = World(config).advance(end_us)
        stamps = [msg.stamp_us for topic, msg in samples(out, 1, end_us, camera=True) if topic == Topic.CAMERA]
        counts[label] = len(stamps)
        if faults:
            where = {int(t): row[0, :2] for t, row in zip(out.truth_stamps, out.truth)}
            inside = [np.hypot(*(where[t] - FOG["center_m"])) <= FOG["radius_m"] for t in stamps]
            counts["fog, made inside the bank"] = int(sum(inside))
    return counts


if __name__ == "__main__":
    print(frames_in_fog())
