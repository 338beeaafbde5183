"""A swarm of 250 on this machine, against 5 and 20 in the same sitting (lockstep `swarm up`, default
configuration): CPU per vehicle per simulated second by role (a long run's CPU minus a short one's,
so that start-up and shutdown cancel out, bench.bench_speed.role_cpu), a vehicle's inbound V2V
frames per second (timing.json: what the bus delivered to it), each role's largest process, the
start-up and shutdown wall time, and 250 vehicles x 60 s against the in-process floor of the same
size (bench.floor). Run by `make bench` (not in the test suite: about 10 minutes)."""

from __future__ import annotations

import json
import statistics
import tempfile
import time
from pathlib import Path

from bench.bench_speed import lockstep, per_vehicle_second_ms, role_cpu
from bench.bench_swarm import floor_wall_s
from bench.common import Row

SIZES = (5, 20, 250)
SCALE_FAULTS = Path(__file__).resolve().parents[1] / "scenarios" / "scale-faults.toml"
SHORT_S, LONG_S = 10, 60  # each size flies both; the long one is the 60 s run the issue asks of 250
MAX_CPU_GROWTH, MAX_INBOUND_GROWTH = 1.3, 1.2
MAX_VEHICLE_RSS_GROWTH = 1.05  # a vehicle at most its size in a small swarm (the issue: 58 MB)


def fly(vehicles: int, duration_s: int, tmp: Path, scenario: Path | None = None) -> dict:
    """One lockstep `swarm up` (over ``scenario``): CPU and peak RSS by role, wall time, timing.json,
    the summary's status, its vehicles scored, its events and the swarm's RMSE."""
    peaks: dict[str, float] = {}
    name = f"scale-{vehicles}-{duration_s}" + (f"-{scenario.stem}" if scenario else "")
    start = time.perf_counter()
    args = (*([str(scenario)] if scenario else []), *lockstep(vehicles, duration_s), "--seed", "1")
    cpu = role_cpu(args, tmp, name, peaks)
    wall = time.perf_counter() - start
    run = tmp / name
    timing = json.loads((run / "timing.json").read_text())
    summary = json.loads((run / "summary.json").read_text())
    return {"cpu": cpu, "peak_rss_mb": peaks, "wall_s": wall, "timing": timing, "status": summary["status"],
            "scored": len(summary["vehicles"]), "events": summary["events"],
            "rmse_m": summary["swarm"]["rmse_m"]}  # fmt: skip


def inbound_per_s(run: dict) -> float:
    """A vehicle's inbound V2V frames per simulated second, the mean over the swarm's vehicles."""
    vehicles = run["timing"]["vehicles"].values()
    return statistics.mean(v.get("v2v_received", 0) for v in vehicles) / run["timing"]["sim_s"]


def run(quick: bool) -> list[Row]:
    sizes = (5, 250) if quick else SIZES
    with tempfile.TemporaryDirectory() as tmp:
        runs = {(n, d): fly(n, d, Path(tmp)) for n in sizes for d in (SHORT_S, LONG_S)}
        faulted = fly(250, LONG_S, Path(tmp), SCALE_FAULTS)
    floor_s = floor_wall_s(250, LONG_S)
    return [*rows(runs, sizes, floor_s), *fault_rows(faulted, runs[250, LONG_S])]


def fault_rows(faulted: dict, clean: dict) -> list[Row]:
    """scenarios/scale-faults.toml against the same swarm without faults: it completes, every killed
    vehicle came back, and what the faults cost the swarm's RMSE."""
    rejoined = faulted["events"].get("vehicle_joined", 0) - 250
    case = "250 vehicles x 60 s, 10 % killed and restarted, one host's links cut for 20 s"
    return [
        Row("scale", case, "completes, every vehicle scored, every killed vehicle back", rejoined, "restarts",
            "25 of 25, status complete, 250 scored",
            faulted["status"] == "complete" and faulted["scored"] == 250 and rejoined == 25,
            {"status": faulted["status"], "scored": faulted["scored"], "events": faulted["events"]}),
        Row("scale", case, "swarm RMSE against the same swarm without faults",
            round(faulted["rmse_m"] / clean["rmse_m"], 3), "x", "- (reported)", None,
            {"faulted_m": faulted["rmse_m"], "clean_m": clean["rmse_m"]}),
    ]  # fmt: skip


def rows(runs: dict[tuple[int, int], dict], sizes: tuple[int, ...], floor_s: float) -> list[Row]:
    """Every row but the faults' from the runs of each size and duration, and the floor's wall time."""
    big = runs[250, LONG_S]
    inbound = [inbound_row(runs, sizes)] if 20 in sizes else []
    return [cpu_row(runs, sizes), *swarm_rows(big, floor_s), *inbound, *startup_rows(runs, sizes),
            *memory_rows(runs[5, LONG_S]["peak_rss_mb"], big["peak_rss_mb"])]  # fmt: skip


def cpu_row(runs: dict[tuple[int, int], dict], sizes: tuple[int, ...]) -> Row:
    """CPU per vehicle per simulated second, 250 against 5, by role in the details."""
    per_vs = {n: per_vehicle_second_ms(runs[n, SHORT_S]["cpu"], runs[n, LONG_S]["cpu"], n, LONG_S - SHORT_S)
              for n in sizes}  # fmt: skip
    growth = sum(per_vs[250].values()) / sum(per_vs[5].values())
    details = {f"{n} vehicles (ms)": {k: round(v, 2) for k, v in roles.items()} for n, roles in per_vs.items()}
    return Row("scale", "CPU per vehicle per simulated second, 250 against 5 vehicles", "ratio", round(growth, 3),
               "x", f"<= {MAX_CPU_GROWTH}x", growth <= MAX_CPU_GROWTH, details)  # fmt: skip


def swarm_rows(big: dict, floor_s: float) -> list[Row]:
    """The 250-vehicle run: complete and scored, and its stepping against the in-process floor."""
    case = "250 vehicles x 60 s, lockstep"
    return [
        Row("scale", case, "completes and scores every vehicle", big["scored"], "vehicles", "250, status complete",
            big["status"] == "complete" and big["scored"] == 250, {"status": big["status"]}),
        Row("scale", case, "wall time / in-process floor", round(big["timing"]["wall_s"] / floor_s, 2), "x",
            "- (reported)", None, {"stepping_wall_s": big["timing"]["wall_s"], "floor_wall_s": round(floor_s, 1),
                                   "real_time_factor": big["timing"]["real_time_factor"]}),
    ]  # fmt: skip


def inbound_row(runs: dict[tuple[int, int], dict], sizes: tuple[int, ...]) -> Row:
    """A vehicle's inbound V2V frames per second, 250 against 20 vehicles."""
    flat = inbound_per_s(runs[250, LONG_S]) / inbound_per_s(runs[20, LONG_S])
    return Row("scale", "a vehicle's inbound V2V frames per second, 250 against 20 vehicles", "ratio",
               round(flat, 3), "x", f"<= {MAX_INBOUND_GROWTH}x", flat <= MAX_INBOUND_GROWTH,
               {f"{n} vehicles (per s)": round(inbound_per_s(runs[n, LONG_S]), 2) for n in sizes})  # fmt: skip


def startup_rows(runs: dict[tuple[int, int], dict], sizes: tuple[int, ...]) -> list[Row]:
    return [
        Row("scale", f"start-up and shutdown, {n} vehicles", "wall time outside the stepping",
            round(runs[n, LONG_S]["wall_s"] - runs[n, LONG_S]["timing"]["wall_s"], 1), "s", "-", None)
        for n in sizes
    ]  # fmt: skip


def memory_rows(small: dict[str, float], large: dict[str, float]) -> list[Row]:
    """Each role's largest process at 250 against 5 vehicles (MB by role)."""
    out = []
    for role in ("sim", "gs"):
        per_vehicle = (large.get(role, 0.0) - small.get(role, 0.0)) / 245
        out.append(
            Row("scale", f"{'world' if role == 'sim' else 'ground station'} process, 250 vehicles",
                "resident memory", round(large.get(role, 0.0), 1), "MB", "- (linear in the swarm)", None,
                {"at 5 vehicles (MB)": round(small.get(role, 0.0), 1), "per vehicle (MB)": round(per_vehicle, 3)})
        )  # fmt: skip
    vehicle_growth = large.get("vehicle", 0.0) / small.get("vehicle", 1.0)
    out.append(
        Row("scale", "vehicle process, 250 against 5 vehicles", "largest resident memory", round(vehicle_growth, 3),
            "x", f"<= {MAX_VEHICLE_RSS_GROWTH}x", vehicle_growth <= MAX_VEHICLE_RSS_GROWTH,
            {"at 5 vehicles (MB)": round(small.get("vehicle", 0.0), 1),
             "at 250 vehicles (MB)": round(large.get("vehicle", 0.0), 1)})
    )  # fmt: skip
    return out
