"""`swarm fault add|kill|list|remove|clear`: edit the fault plan of a running swarm.

The command asks the ground station's queryable (``<prefix>/ctl/faults/request``); the ground
station validates the change against the swarm, applies it, publishes the new plan and answers.
The grammar is close to netem and toxiproxy::

    swarm fault add delay --to 'v*' --topic mavlink --delay 200ms --jitter 50ms
    swarm fault add loss --to v3 --percent 30 [--burst 5]
    swarm fault add jam-gnss --center 40,10 --radius 25m --for 60s
    swarm fault kill v2 --restart-after 10s
    swarm fault add lie --vehicle v3 --offset 30,-30 --cov-scale 0.01 --for 60s
    swarm fault add lie --vehicle v3 --stale 5s
    swarm fault add accuse --vehicle v3 --names v1,v2
"""

from __future__ import annotations

import json
import os
import re
from pathlib import Path
from typing import Optional

import typer

from bus.errors import ConfigError, SwarmlocError
from cli.errors import fail

fault_app = typer.Typer(no_args_is_help=True, help="Inspect and change the fault plan of a running swarm.")
# bus.faults' LINK_KINDS, PHYSICAL_KINDS and BEHAVIOUR_KINDS (a test keeps them equal; importing bus.faults
# here would load pydantic and numpy into every process that starts the CLI)
KINDS = ("delay", "loss", "duplicate", "reorder", "jam-gnss", "spoof-gnss", "jam-comms", "blackout", "lie", "accuse")
_UNITS_S = {"us": 1e-6, "ms": 1e-3, "s": 1.0, "min": 60.0, "": 1.0}
_UNITS_M = {"m": 1.0, "km": 1000.0, "": 1.0}
REPLY_TIMEOUT_S = 5.0
FLAGS = {
    "delay_s": "--delay",
    "jitter_s": "--jitter",
    "gap_s": "--gap",
    "radius_m": "--radius",
    "center_m": "--center",
    "drift_mps": "--drift",
    "heading_deg": "--heading",
    "for_s": "--for",
    "start_s": "--in",
    "dst": "--to",
    "src": "--from",
    "restart_after_s": "--restart-after",
    "percent": "--percent",
    "burst": "--burst",
    "offset_m": "--offset",
    "cov_scale": "--cov-scale",
    "vehicle": "--vehicle",
    "names": "--names",
    "stale_s": "--stale",
}


def _quantity(text: str, units: dict[str, float], what: str) -> float:
    match = re.fullmatch(r"\s*([-+]?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?)\s*([a-z]*)\s*", text)
    if not match or match.group(2) not in units:
        raise ConfigError(f"{what}: cannot read {text!r} (units: {', '.join(u for u in units if u)})")
    return float(match.group(1)) * units[match.group(2)]


def seconds(text: str | None, what: str) -> float | None:
    """'200ms', '10s', '1.5', '2min' -> seconds (None stays None)."""
    return None if text is None else _quantity(text, _UNITS_S, what)


def metres(text: str | None, what: str) -> float | None:
    return None if text is None else _quantity(text, _UNITS_M, what)


def percent(text: str | None) -> float | None:
    return None if text is None else _quantity(text.rstrip("%"), {"": 1.0}, "--percent")


def centre(text: str | None, flag: str = "--center") -> list[float] | None:
    """'X,Y' in metres (units allowed on each) -> [x, y]."""
    if text is None:
        return None
    parts = text.split(",")
    if len(parts) != 2:
        raise ConfigError(f"{flag}: expected X,Y in metres, got {text!r}")
    return [metres(p, flag) for p in parts]


def vehicle_number(text: str) -> int:
    match = re.fullmatch(r"v?(\d+)", text.strip())
    if not match:
        raise ConfigError(f"not a vehicle: {text!r} (use v<id> or <id>)")
    return int(match.group(1))


def vehicle_numbers(text: str, flag: str) -> list[int]:
    """'v1,v2' or '1,2' -> [1, 2]."""
    try:
        return [vehicle_number(part) for part in text.split(",")]
    except ConfigError as exc:
        raise ConfigError(f"{flag}: {exc}") from None


def find_swarm(out: Path, run: Optional[Path], connect: Optional[str]) -> tuple[tuple[str, ...], str, dict[str, str]]:
    """Endpoints, key prefix and login environment of the swarm to talk to: --connect, --run,
    $SWARMLOC_ZENOH_CONNECT, or the newest run under ``out`` whose `swarm up` is still running
    (its handle names the CLI's credentials). Logins otherwise come from $SWARMLOC_ZENOH_USER etc."""
    prefix = os.environ.get("SWARMLOC_PREFIX") or "swarm"
    env = dict(os.environ)
    if connect:
        return tuple(c.strip() for c in connect.split(",")), prefix, env
    if run is None and os.environ.get("SWARMLOC_ZENOH_CONNECT"):
        return tuple(c.strip() for c in os.environ["SWARMLOC_ZENOH_CONNECT"].split(",")), prefix, env
    handles = [run / "swarm.json"] if run else sorted(out.glob("*/swarm.json"), key=lambda p: p.stat().st_mtime)
    for handle in reversed(handles):
        try:
            info = json.loads(handle.read_text())
            os.kill(int(info["pid"]), 0)
        except (OSError, ValueError, KeyError, TypeError):
            continue
        return tuple(info["connect"]), str(info.get("prefix", prefix)), {**env, **info.get("env", {})}
    where = str(run) if run else f"{out}/*/swarm.json"
    raise SwarmlocError(f"no swarm running ({where}: no live `swarm up`); start one or give --connect")


def ask(request: dict, out: Path, run: Optional[Path], connect: Optional[str]) -> dict:
    """Send one request to the swarm's ground station; its reply, or SwarmlocError."""
    from pydantic import ValidationError

    from bus.config import BusConfig
    from bus.errors import DecodeError
    from bus.plan import FaultReply, FaultRequest, decode_json, encode_json

    try:
        payload = encode_json(FaultRequest.model_validate(request))
    except ValidationError as exc:
        first = exc.errors()[0]
        field = str(first["loc"][-1]) if first["loc"] else "fault"
        message = first["msg"].removeprefix("Value error, ")
        where = "" if field in KINDS else f"{FLAGS.get(field, field)}: "  # a whole fault's check names its flags
        raise ConfigError(f"invalid fault: {where}{message}") from None
    endpoints, prefix, env = find_swarm(out, run, connect)
    reply = _query(BusConfig(mode="client", connect=endpoints, prefix=prefix), payload, env)
    if reply is None:
        raise SwarmlocError(f"no swarm answered at {', '.join(endpoints)} (is its ground station running?)")
    try:
        return decode_json(FaultReply, reply).model_dump(mode="json")
    except DecodeError as exc:
        raise SwarmlocError(f"the ground station sent a malformed reply: {exc}") from None


def _query(conf, payload: bytes, env: dict[str, str]) -> bytes | None:
    from bus.errors import BusUnavailable
    from bus.session import Transport, ZenohBus

    try:
        bus = ZenohBus(conf, role="cli", transport=Transport.from_env(env))
    except BusUnavailable as exc:
        raise SwarmlocError(f"no swarm reachable: {exc}") from None
    with bus:
        replies = bus.get(bus.keys.fault_request(), payload, REPLY_TIMEOUT_S)
    return replies[0] if replies else None


def _finish(reply: dict, *, show_plan: bool) -> None:
    from rich.console import Console
    from rich.table import Table

    if not reply["ok"]:
        fail(reply["error"])
    if not show_plan:
        typer.echo(f"ok (plan version {reply['plan']['version']}, sim time {reply['sim_time_s']:.2f} s)")
        return
    table = Table(title=f"fault plan v{reply['plan']['version']} at sim time {reply['sim_time_s']:.2f} s")
    for column in ("name", "kind", "state", "parameters"):
        table.add_column(column)
    for state in reply["states"]:
        table.add_row(state["name"], state["kind"], state["state"], state["description"])
    Console().print(table)


def _run(request: dict, out: Path, run: Optional[Path], connect: Optional[str], *, show_plan: bool = False) -> None:
    try:
        reply = ask(request, out, run, connect)
    except SwarmlocError as exc:
        fail(str(exc))
    _finish(reply, show_plan=show_plan)


OUT = typer.Option(Path("runs"), help="where `swarm up` writes its runs (the newest live one is used)")
RUN = typer.Option(None, help="the run directory of the swarm to talk to")
CONNECT = typer.Option(None, help="zenoh endpoint(s) of the swarm's router, e.g. tcp/10.0.0.2:7447")


@fault_app.command()
def add(
    kind: str = typer.Argument(..., help=f"one of: {', '.join(KINDS)}"),
    to: Optional[str] = typer.Option(None, "--to", help="link faults: receiving endpoint glob (v*, v3, gs)"),
    src: Optional[str] = typer.Option(None, "--from", help="link faults: sending endpoint glob"),
    topic: Optional[str] = typer.Option(None, help="link faults: topic glob (imu, odom, gnss, ranging, seen, mavlink)"),
    delay: Optional[str] = typer.Option(None, help="delay: e.g. 200ms"),
    jitter: Optional[str] = typer.Option(None, help="delay: e.g. 50ms"),
    distribution: Optional[str] = typer.Option(None, help="delay: uniform, normal or pareto"),
    percent_: Optional[str] = typer.Option(None, "--percent", help="loss, duplicate, reorder: share of packets"),
    burst: Optional[float] = typer.Option(None, help="loss: mean burst length in packets (Gilbert-Elliott)"),
    gap: Optional[str] = typer.Option(None, help="reorder: how long a held-back packet waits, e.g. 100ms"),
    center: Optional[str] = typer.Option(None, help="zones: X,Y in metres"),
    radius: Optional[str] = typer.Option(None, help="zones: e.g. 25m"),
    drift: Optional[float] = typer.Option(None, help="spoof-gnss, lie: offset growth in m/s"),
    heading: Optional[float] = typer.Option(None, help="spoof-gnss, lie: direction of the growth in degrees (0 = +x)"),
    offset: Optional[str] = typer.Option(None, help="lie: constant offset X,Y in metres of the broadcast position"),
    cov_scale: Optional[float] = typer.Option(None, help="lie: broadcast covariance times this (0.01: 100x too sure)"),
    stale: Optional[str] = typer.Option(None, help="lie: broadcast the estimate of this long before, e.g. 5s"),
    vehicle: Optional[str] = typer.Option(None, help="blackout, lie, accuse: the vehicle (v3 or 3)"),
    names: Optional[str] = typer.Option(None, help="accuse: the vehicles it accuses, e.g. v1,v2"),
    sensor: Optional[str] = typer.Option(None, help="blackout: imu, odom, gnss or ranging"),
    name: Optional[str] = typer.Option(None, help="a unique name (default: <kind>-<n>)"),
    in_: Optional[str] = typer.Option(None, "--in", help="start this long from now (default: now)"),
    for_: Optional[str] = typer.Option(None, "--for", help="how long it lasts (default: to the end of the run)"),
    out: Path = OUT,
    run: Optional[Path] = RUN,
    connect: Optional[str] = CONNECT,
) -> None:
    """Add a fault to the running swarm's plan (starts now unless --in is given)."""
    try:
        if kind not in KINDS:
            raise ConfigError(f"unknown fault kind {kind!r}; known: {', '.join(KINDS)} (and `swarm fault kill`)")
        fields = {
            "kind": kind,
            "name": name,
            "dst": to,
            "src": src,
            "topic": topic,
            "delay_s": seconds(delay, "--delay"),
            "jitter_s": seconds(jitter, "--jitter"),
            "distribution": distribution,
            "percent": percent(percent_),
            "burst": burst,
            "gap_s": seconds(gap, "--gap"),
            "center_m": centre(center),
            "radius_m": metres(radius, "--radius"),
            "drift_mps": drift,
            "heading_deg": heading,
            "offset_m": centre(offset, "--offset"),
            "cov_scale": cov_scale,
            "sensor": sensor,
            "stale_s": seconds(stale, "--stale"),
            "vehicle": vehicle_number(vehicle) if vehicle else None,
            "names": vehicle_numbers(names, "--names") if names else None,
            "start_s": seconds(in_, "--in"),
            "for_s": seconds(for_, "--for"),
        }
    except ConfigError as exc:
        fail(str(exc))
    fault = {k: v for k, v in fields.items() if v is not None}
    _run({"op": "add", "fault": fault, "relative": True}, out, run, connect)


@fault_app.command()
def kill(
    vehicle: str = typer.Argument(..., help="the vehicle to SIGKILL (v2 or 2)"),
    restart_after: Optional[str] = typer.Option(None, help="start it again this much sim time later, e.g. 10s"),
    name: Optional[str] = typer.Option(None, help="a unique name (default: kill-<n>)"),
    in_: Optional[str] = typer.Option(None, "--in", help="kill this long from now (default: now)"),
    out: Path = OUT,
    run: Optional[Path] = RUN,
    connect: Optional[str] = CONNECT,
) -> None:
    """Kill a vehicle process (SIGKILL) and optionally restart it (needs `swarm up` as supervisor)."""
    try:
        fault = {
            "kind": "kill",
            "vehicle": vehicle_number(vehicle),
            "name": name,
            "restart_after_s": seconds(restart_after, "--restart-after"),
            "start_s": seconds(in_, "--in"),
        }
    except ConfigError as exc:
        fail(str(exc))
    _run({"op": "add", "fault": {k: v for k, v in fault.items() if v is not None}, "relative": True}, out, run, connect)


@fault_app.command("list")
def list_(out: Path = OUT, run: Optional[Path] = RUN, connect: Optional[str] = CONNECT) -> None:
    """Print the plan: every fault with its state (pending, active, expired)."""
    _run({"op": "list"}, out, run, connect, show_plan=True)


@fault_app.command()
def remove(
    name: str = typer.Argument(..., help="the fault's name (see `swarm fault list`)"),
    out: Path = OUT,
    run: Optional[Path] = RUN,
    connect: Optional[str] = CONNECT,
) -> None:
    """Remove one fault from the plan (an active fault stops at once)."""
    _run({"op": "remove", "name": name}, out, run, connect)


@fault_app.command()
def clear(out: Path = OUT, run: Optional[Path] = RUN, connect: Optional[str] = CONNECT) -> None:
    """Remove every fault from the plan."""
    _run({"op": "clear"}, out, run, connect)
