"""Report rendering time for a 5-vehicle, 60 s lockstep run (figures and HTML).

Target: <= 15 s, so `swarm up` is not held up noticeably by its report.
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench.common import Row

TARGET_S = 15.0


def run(quick: bool = False) -> list[Row]:
    from groundstation.report import write_report

    duration = 20 if quick else 60
    with tempfile.TemporaryDirectory() as tmp:
        subprocess.run(
            [
                sys.executable,
                "-m",
                "cli",
                "up",
                "--quiet",
                "--out",
                tmp,
                "--name",
                "r",
                "--vehicles",
                "5",
                "--duration",
                str(duration),
                "--seed",
                "1",
            ],
            capture_output=True,
            text=True,
            timeout=900,
        )
        best = float("inf")
        for _ in range(3):
            start = time.perf_counter()
            write_report(Path(tmp) / "r")
            best = min(best, time.perf_counter() - start)
        html_mb = (Path(tmp) / "r" / "report.html").stat().st_size / 2**20
    return [
        Row(
            "report",
            f"5 vehicles, {duration} s",
            "render time",
            round(best, 2),
            "s",
            f"<= {TARGET_S:g} s",
            best <= TARGET_S,
            {"html_mb": round(html_mb, 2)},
        )
    ]
