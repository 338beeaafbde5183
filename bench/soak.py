"""Soak: a realtime swarm of 5 vehicles for 10 minutes of wall time under a steady trickle of hostile
traffic (a compromised vehicle's login: garbage, oversized, impersonating and degenerate frames,
bad liveliness tokens), with the resident memory of every process sampled from /proc. Memory must
stay bounded: RSS grows by less than 10% from minute 2 to the end.

Usage: python -m bench.soak [--minutes M] (make soak); prints a table and writes bench/soak.json.
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent
WARM_S = 120.0


def rss_by_role(run: Path) -> dict[str, float]:
    """Resident memory (MB) of each process of the run, named by role (router, world, gs, vehicle-N)."""
    out = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            cmd = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
            rss = next(
                int(line.split()[1]) for line in (entry / "status").read_text().splitlines() if line.startswith("VmRSS")
            )
        except (OSError, StopIteration):
            continue
        if " -m cli " not in cmd:
            continue
        if f"{run}/vehicle.json" in cmd:
            out[f"vehicle-{cmd.split('--id ')[1].split()[0]}"] = rss / 1024
        elif f"{run}/config.json" in cmd:
            out["world" if " sim " in cmd else "groundstation"] = rss / 1024
        elif " router " in cmd and str(run) in cmd:
            out["router"] = rss / 1024
    return out


def hostile_trickle(run: Path, stop: threading.Event, rate_hz: float = 50.0) -> int:
    """Vehicle 5's login and key, sending a rotating set of hostile messages; returns how many."""
    from bus.config import BusConfig
    from bus.mavlink_codec import MavlinkEncoder, StateEstimate
    from bus.session import Transport, ZenohBus

    secrets = run / "secrets"
    endpoint = json.loads((run / "swarm.json").read_text())["connect"][0]
    key = bytes.fromhex((secrets / "vehicle-5.key").read_text().strip())
    login = Transport(user="vehicle-5", password=(secrets / "vehicle-5.password").read_text().strip())
    as_two = MavlinkEncoder(vehicle_id=2, signing_key=key, link_id=1)
    degenerate = MavlinkEncoder(vehicle_id=5, signing_key=key, link_id=2)
    rng, sent = np.random.default_rng(7), 0
    with ZenohBus(BusConfig(connect=(endpoint,)), role="groundstation", transport=login) as bus:
        pubs = {
            k: bus.publisher(f"swarm/{k}") for k in ("v/5/mavlink", "v/5/v2v", "v/x/v2v", "v/5/status", "ctl/ack/5")
        }
        while not stop.wait(1.0 / rate_hz):
            k = sent % 8
            est = StateEstimate(
                2 if k == 2 else 5,
                1_000_000 + sent,
                np.array([1.0, 2.0, -30.0]),
                0.0,
                np.zeros(3),
                0.0,
                np.zeros((6, 6)) if k == 3 else np.eye(6),
                np.eye(6),
            )
            if k == 0:
                pubs["v/5/mavlink"].put(rng.bytes(int(rng.integers(1, 400))))
            elif k == 1:
                pubs["v/5/v2v"].put(b"\xfd" * 5_000)
            elif k == 2:
                pubs["v/5/mavlink"].put(as_two.odometry(est))
            elif k == 3:
                pubs["v/5/mavlink"].put(degenerate.odometry(est))
            elif k == 4:
                pubs["v/x/v2v"].put(rng.bytes(50))
            elif k == 5:
                pubs["v/5/status"].put(rng.bytes(30))
            elif k == 6:
                pubs["ctl/ack/5"].put(rng.bytes(20))
            else:
                token = bus._session.liveliness().declare_token(f"swarm/alive/vehicle/{sent % 1000}x")
                token.undeclare()
            sent += 1
    return sent


def main() -> None:
    minutes = float(sys.argv[sys.argv.index("--minutes") + 1]) if "--minutes" in sys.argv else 10.0
    duration_s = minutes * 60.0
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        cmd = [
            sys.executable,
            "-m",
            "cli",
            "up",
            "--quiet",
            "--out",
            str(out),
            "--name",
            "soak",
            "--vehicles",
            "5",
            "--mode",
            "realtime",
            "--duration",
            str(duration_s),
            "--seed",
            "3",
        ]
        swarm = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        run = out / "soak"
        while not (run / "swarm.json").exists() or not (run / "metrics.csv").exists():
            time.sleep(0.5)
        stop, counter = threading.Event(), {}
        attacker = threading.Thread(target=lambda: counter.update(sent=hostile_trickle(run, stop)), daemon=True)
        attacker.start()
        start, samples = time.monotonic(), []
        while swarm.poll() is None:
            samples.append((time.monotonic() - start, rss_by_role(run)))
            time.sleep(10.0)
        stop.set()
        attacker.join(10)
        output = swarm.communicate()[0]
        summary = json.loads((run / "summary.json").read_text())
    report(samples, summary, counter.get("sent", 0), swarm.returncode, output, minutes)


def report(samples, summary, hostile, exit_status, output, minutes) -> None:
    warm = next(rss for t, rss in samples if t >= min(WARM_S, samples[-1][0] / 2))
    end = {}  # each process's last sample while it ran (vehicles and the world leave before the rest)
    for _, rss in samples:
        end.update(rss)
    rows = []
    for role in sorted(warm):
        if role in end:
            growth = 100.0 * (end[role] - warm[role]) / warm[role]
            rows.append(
                {
                    "process": role,
                    "rss_minute2_mb": round(warm[role], 1),
                    "rss_end_mb": round(end[role], 1),
                    "growth_percent": round(growth, 2),
                    "met": growth < 10.0,
                }
            )
    lines = [
        "| process | RSS at minute 2 [MB] | RSS at the end [MB] | growth | < 10% |",
        "| --- | ---: | ---: | ---: | --- |",
    ]
    lines += [
        f"| {r['process']} | {r['rss_minute2_mb']} | {r['rss_end_mb']} | {r['growth_percent']:+.2f}% | "
        f"{'yes' if r['met'] else '**no**'} |"
        for r in rows
    ]
    scored = {vid: v["samples"] for vid, v in summary["vehicles"].items()}
    print("\n".join(lines))
    print(f"hostile messages sent: {hostile}; rejected by reason: {summary['rejected']['by_reason']}")
    print(f"run status: {summary['status']}, exit {exit_status}; estimates scored per vehicle: {scored}")
    result = {
        "minutes": minutes,
        "rows": rows,
        "hostile_messages": hostile,
        "rejected": summary["rejected"],
        "status": summary["status"],
        "exit_status": exit_status,
        "scored": scored,
        "table": "\n".join(lines),
        "rss_samples": samples,
    }
    (ROOT / "soak.json").write_text(json.dumps(result, indent=2) + "\n")
    if exit_status != 0:
        print(output[-3000:])


if __name__ == "__main__":
    main()
