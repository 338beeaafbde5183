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

import inspect
import json
import os
from pathlib import Path
from typing import Optional

import typer

from bus.errors import ConfigError, SwarmlocError
from bus.faults import BY_KIND
from cli.errors import fail
from cli.fault_flags import addable_kinds, flags, with_flag_options
from cli.quantities import seconds, vehicle_number

fault_app = typer.Typer(no_args_is_help=True, help="Inspect and change the fault plan of a running swarm.")
REPLY_TIMEOUT_S = 5.0
FLAGS = {name: flag.flag for name, flag in flags().items()}  # field -> flag, every kind's (error messages)


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
        where = "" if field in BY_KIND else f"{FLAGS.get(field, field)}: "  # a whole fault's check names its flags
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


def add(**values: Optional[str]) -> None:
    """Add a fault to the running swarm's plan (starts now unless --in is given). Its flags are the
    fields the fault kinds declare (cli.fault_flags)."""
    kind = values.pop("kind")
    out, run, connect = values.pop("out"), values.pop("run"), values.pop("connect")
    try:
        if kind not in addable_kinds():
            raise ConfigError(
                f"unknown fault kind {kind!r}; known: {', '.join(addable_kinds())} (and `swarm fault kill`)"
            )
        fault = {"kind": kind}
        for name, flag in ADD_FLAGS.items():
            text = values.get(flag.param)
            if text is not None:
                fault[name] = flag.value(text)
    except ConfigError as exc:
        fail(str(exc))
    _run({"op": "add", "fault": fault, "relative": True}, out, run, connect)


ADD_FLAGS = flags(addable_kinds())
_REST = [
    inspect.Parameter(name, inspect.Parameter.KEYWORD_ONLY, default=default, annotation=annotation)
    for name, default, annotation in (
        ("out", OUT, Path),
        ("run", RUN, Path | None),
        ("connect", CONNECT, str | None),
    )
]
fault_app.command()(with_flag_options(add, ADD_FLAGS, _REST))


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
