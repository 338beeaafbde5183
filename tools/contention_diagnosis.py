"""Where a vehicle's CPU per simulated second goes as the swarm grows on a few cores: lockstep `swarm up`
of N vehicles for a short and a long duration, every process's user and system time and its voluntary
and involuntary context switches read from /proc while it runs; the long run's minus the short one's
per vehicle per simulated second (start-up and shutdown cancel out). docs/decisions/scale.md has the
table.

    python tools/contention_diagnosis.py [--vehicles 5,250] [--durations 10,40]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

FIELDS = ("user [ms]", "system [ms]", "voluntary switches", "involuntary switches")


def sample(marker: str, seen: dict[int, tuple[str, tuple[float, ...]]]) -> None:
    """The counters of every process of the run (its command line names ``marker``), newest reading."""
    hz = os.sysconf("SC_CLK_TCK")
    for entry in os.scandir("/proc"):
        if not entry.name.isdigit():
            continue
        try:
            cmd = Path(entry.path, "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
            if marker not in cmd or not cmd.startswith("swarm "):
                continue
            stat = Path(entry.path, "stat").read_text()
            fields = stat[stat.rindex(")") + 2 :].split()
            status = Path(entry.path, "status").read_text()
            switches = [
                int(status.split(f"{kind}_ctxt_switches:")[1].split()[0]) for kind in ("\nvoluntary", "nonvoluntary")
            ]
            seen[int(entry.name)] = (cmd.split()[1], (int(fields[11]) / hz, int(fields[12]) / hz, *switches))
        except (OSError, ValueError, IndexError):
            continue


def fly(vehicles: int, duration_s: int, out: Path) -> dict[str, list[float]]:
    """Each role's summed counters over one lockstep run."""
    name = f"n{vehicles}-{duration_s}"
    args = ["--vehicles", str(vehicles), "--duration", str(duration_s), "--mode", "lockstep", "--seed", "1"]
    args += ["--out", str(out), "--name", name, "--quiet", "--no-report", "--no-record"]
    process = subprocess.Popen(
        [sys.executable, "-m", "cli", "up", *args], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
    )
    seen: dict[int, tuple[str, tuple[float, ...]]] = {}
    while process.poll() is None:
        sample(f"{out / name}/", seen)
        time.sleep(0.05)
    totals: dict[str, list[float]] = {}
    for role, counters in seen.values():
        totals[role] = [a + b for a, b in zip(totals.get(role, [0.0] * len(FIELDS)), counters)]
    return totals


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--vehicles", default="5,250")
    parser.add_argument("--durations", default="10,40")
    options = parser.parse_args()
    short, long = map(int, options.durations.split(","))
    print(f"| vehicles | role | {' | '.join(FIELDS)} (per vehicle per simulated second) |")
    print("| ---: | --- |" + " ---: |" * len(FIELDS))
    with tempfile.TemporaryDirectory() as tmp:
        for n in map(int, options.vehicles.split(",")):
            a, b = fly(n, short, Path(tmp)), fly(n, long, Path(tmp))
            for role in sorted(b):
                per = [(y - x) / (n * (long - short)) for x, y in zip(a.get(role, [0.0] * len(FIELDS)), b[role])]
                scaled = [per[0] * 1e3, per[1] * 1e3, per[2], per[3]]  # ms, ms, switches, switches
                print(f"| {n} | {role} | " + " | ".join(f"{v:.2f}" for v in scaled) + " |")


if __name__ == "__main__":
    main()
