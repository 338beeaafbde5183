"""Adding a sensor, shown to work: ``compare`` flies one vehicle with its GNSS jammed all flight on
seeded worlds that have a compass (bus/sensors/compass.py), once with the compass's filter part and
once without it (the same world: the filter without the part ignores the headings), and returns each
one's heading error and pose ANEES (docs/tutorial/adding-a-sensor.md; the tests run it). Pure: the
world and the filters in this process, no bus."""

from __future__ import annotations

import numpy as np

from bus import statistics
from bus.config import build_config
from experiments.harness import Listener, pose_score, run
from sim.world import World
from vehicle.estimators import get_estimator

JAMMED = [{"kind": "jam-gnss", "center_m": [0.0, 0.0], "radius_m": 100_000.0, "start_s": 10.0}]


def compare(seeds: range, *, duration_s: float = 60.0) -> dict[str, dict[str, float]]:
    """Per filter ("compass", "no compass"): heading error RMS (rad) and pose ANEES, scored every
    second once the jam began, over ``seeds``."""
    scores: dict[str, dict[str, list[float]]] = {
        name: {"heading": [], "nees": []} for name in ("compass", "no compass")
    }
    for seed in seeds:
        world = {"vehicles": 1, "seed": seed, "trajectories": ["figure8"]}
        with_compass = build_config(
            {
                "world": world,
                "clock": {"duration_s": duration_s},
                "sensors": {"compass": {"rate_hz": 5}},
                "faults": JAMMED,
            }
        )
        filters = {
            "compass": get_estimator(with_compass.for_vehicle(), 1),  # the compass is on: its part is added
            "no compass": get_estimator(build_config({"world": world}).for_vehicle(), 1),
        }

        def score(t_us: int, truth: np.ndarray | None) -> None:
            if t_us % 1_000_000 == 0 and t_us >= 11_000_000:
                for name, f in filters.items():
                    scores[name]["heading"].append(statistics.pose_error(f.state.x[:3], truth[0, :3])[2])
                    scores[name]["nees"].append(pose_score(f, truth[0, :3])[0])

        run(
            World(with_compass),
            [Listener((1,), f) for f in filters.values()],
            end_us=round(duration_s * 1e6),
            on_cycle=score,
        )
    return {
        name: {
            "heading_rms_rad": float(np.sqrt(np.mean(np.square(s["heading"])))),
            "anees": float(np.mean(s["nees"])),
        }
        for name, s in scores.items()
    }


if __name__ == "__main__":
    print(compare(range(1, 11)))
