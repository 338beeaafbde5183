"""What each process of a swarm loads when it starts, and what that costs: a probe per role runs, in a
fresh interpreter, what `python -m cli <role>` does before its loop (the CLI's import, the role's
command's imports, zenoh, the node built from a configuration over the in-memory bus instead of a
zenoh session) and reports the heavy libraries it loaded, its CPU time and its resident memory.
The import-set test (tests/test_process_imports.py) and the start-up benchmark
(bench/bench_startup.py) both run it."""

from __future__ import annotations

import json
import resource
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
HEAVY = ("cv2", "scipy", "matplotlib", "foxglove", "rich", "typer", "click", "zenoh", "pymavlink", "pydantic")
CAMERA = {  # a camera UAV of the vision-slam experiment
    "world": {"trajectories": ["circle"], "vehicles": 1},
    "sensors": {"camera_rate_hz": 10.0},
    "vehicle": {"estimator": "ekf-slam", "cooperation": {"enabled": False}},
}
ROLES: dict[str, tuple[str, dict]] = {  # name: (role, build_config input)
    "vehicle": ("vehicle", {}),
    "vehicle with a camera": ("vehicle", CAMERA),
    "world": ("world", {}),
    "ground station": ("groundstation", {}),
}
_PROBE = """
import json, resource, sys, time
import cli.main  # what `python -m cli` loads
import zenoh  # the bus opens a session
from bus.config import build_config
from bus.memory import MemoryHub
config = build_config(json.loads(sys.argv[2]))
hub = MemoryHub()
role = sys.argv[1]
if role == "vehicle":
    from bus.secrets import signing_key_from_env
    from vehicle.process.loops import run_vehicle
    from vehicle.process.node import VehicleNode
    node = VehicleNode(hub.connect("vehicle"), config.for_vehicle(), 1)
elif role == "world":
    from sim.node import WorldNode, run_world
    node = WorldNode(hub.connect("world"), config)
else:
    import tempfile
    from groundstation.display import live_display
    from groundstation.node import GroundStation
    from groundstation.station_loop import run_groundstation
    node = GroundStation(hub.connect("groundstation"), config, __import__("pathlib").Path(tempfile.mkdtemp()))
    node.finish("probe")
print(json.dumps({"modules": sorted(m for m in sys.argv[3].split(",") if m in sys.modules),
                  "rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))
"""


@dataclass(frozen=True)
class Startup:
    """One role's start-up: heavy libraries loaded, CPU seconds (interpreter included), peak RSS (MB)."""

    modules: tuple[str, ...]
    cpu_s: float
    rss_mb: float
    wall_s: float


def probe(name: str) -> Startup:
    """Start the role ``name`` of ROLES in a fresh interpreter as its process would, up to its loop."""
    role, config = ROLES[name]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    result = subprocess.run(
        [sys.executable, "-c", _PROBE, role, json.dumps(config), ",".join(HEAVY)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
        env={"OPENBLAS_NUM_THREADS": "1", "PATH": "/usr/bin:/bin"},
    )
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if result.returncode != 0:
        raise RuntimeError(f"the {name} probe failed: {result.stderr[-2000:]}")
    found = json.loads(result.stdout.strip().splitlines()[-1])
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return Startup(tuple(found["modules"]), cpu, found["rss_mb"], wall)
