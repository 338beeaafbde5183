"""What run.mcap and the live view cost: the 5-vehicle demo (lockstep, 60 s) with nothing, with run.mcap
(the default) and with run.mcap plus ``--live`` and one WebSocket client subscribed to every channel,
interleaved over ``ROUNDS`` rounds (7: one round to the next differs by up to 15 %) so the ratios
come from one run on one machine; and the MCAP bytes per vehicle per simulated minute. Target:
run.mcap costs the lockstep run under 5 % of its speed (then it is on by default, as it is)."""

from __future__ import annotations

import json
import resource
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

from bench.common import Row

VEHICLES, DURATION_S, ROUNDS = 5, 60.0, 7
TARGET_COST = 0.05


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _viewer(port: int, stop: threading.Event, received: list[int]) -> None:
    """A Foxglove WebSocket client that subscribes to every advertised channel and reads until ``stop``."""
    from websockets.sync.client import connect

    client = None
    while client is None and not stop.is_set():
        try:
            client = connect(f"ws://127.0.0.1:{port}", subprotocols=["foxglove.sdk.v1", "foxglove.websocket.v1"])
        except OSError:
            time.sleep(0.05)
    if client is None:
        return
    with client:
        next_id = 1
        while not stop.is_set():
            try:
                frame = client.recv(timeout=0.5)
            except TimeoutError:
                continue
            except Exception:
                return
            if isinstance(frame, str):
                message = json.loads(frame)
                if message.get("op") == "advertise":
                    subscriptions = [
                        {"id": next_id + k, "channelId": c["id"]} for k, c in enumerate(message["channels"])
                    ]
                    next_id += len(subscriptions)
                    client.send(json.dumps({"op": "subscribe", "subscriptions": subscriptions}))
            else:
                received[0] += 1


def run_once(out: Path, name: str, flags: list[str]) -> tuple[float, int, float]:
    """(real-time factor, run.mcap bytes, CPU seconds of all its processes) of one demo run with ``flags``."""
    port = _free_port()
    live = "--live" in flags
    stop, received = threading.Event(), [0]
    viewer = threading.Thread(target=_viewer, args=(port, stop, received), daemon=True) if live else None
    if viewer is not None:
        viewer.start()
    command = [sys.executable, "-m", "cli", "up", "--quiet", "--no-report", "--out", str(out), "--name", name]
    command += ["--vehicles", str(VEHICLES), "--duration", str(DURATION_S), "--mode", "lockstep", "--seed", "1"]
    command += flags + (["--live-port", str(port)] if live else [])
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run(command, check=True, capture_output=True, timeout=1800)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu_s = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
    stop.set()
    if viewer is not None:
        viewer.join(timeout=5)
    rtf = json.loads((out / name / "timing.json").read_text())["real_time_factor"]
    mcap = out / name / "run.mcap"
    return rtf, (mcap.stat().st_size if mcap.exists() else 0), cpu_s


def run(quick: bool = False) -> list[Row]:
    cases = {"nothing": ["--no-record"], "run.mcap": [], "run.mcap + live": ["--live"]}
    rtf: dict[str, list[float]] = {name: [] for name in cases}
    cpu: dict[str, list[float]] = {name: [] for name in cases}
    size = []
    with tempfile.TemporaryDirectory() as tmp:
        for round_ in range(1 if quick else ROUNDS):
            for name, flags in cases.items():
                print(f"  recording: {name}, round {round_ + 1} ...", flush=True)
                run_name = f"{name.replace(' ', '').replace('+', '-')}-{round_}"
                factor, nbytes, cpu_s = run_once(Path(tmp), run_name, flags)
                rtf[name].append(factor)
                cpu[name].append(cpu_s)
                if name == "run.mcap":
                    size.append(nbytes)
    base = float(np.median(rtf["nothing"]))
    rows = []
    for name in ("run.mcap", "run.mcap + live"):
        cost = 1.0 - float(np.median(rtf[name])) / base
        target, met = (f"< {TARGET_COST:.0%} slower", cost < TARGET_COST) if name == "run.mcap" else ("-", None)
        details = {"rtf_median": round(float(np.median(rtf[name])), 2), "rtf_nothing_median": round(base, 2)}
        details["rtf_all"] = [round(v, 2) for v in rtf[name]]
        details["cpu_s_median"] = round(float(np.median(cpu[name])), 2)
        details["cpu_s_nothing_median"] = round(float(np.median(cpu["nothing"])), 2)
        rows.append(
            Row(
                "recording",
                f"{name}, demo (5 vehicles, lockstep)",
                "cost in speed",
                round(100 * cost, 1),
                "%",
                target,
                met,
                details,
            )
        )
    per_vehicle_minute = float(np.median(size)) / VEHICLES / (DURATION_S / 60.0)
    rows.append(
        Row(
            "recording",
            "run.mcap, demo",
            "bytes per vehicle per simulated minute",
            round(per_vehicle_minute / 1e3, 1),
            "kB",
            "-",
            None,
        )
    )
    return rows
