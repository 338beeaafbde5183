"""A compromised insider against a running swarm (real processes, lockstep).

Secure swarm: the attacker holds vehicle 3's login and signing key. It tries to speak for others
(the router refuses), sends hostile but well-formed traffic on its own keys (impersonating frames,
acks and status, unknown sysids, degenerate covariances, far-off stamps, oversized and truncated
payloads) and floods 10,000 messages in about a second. Insecure swarm: nobody filters anything, and
the cases of the threat model's table (docs/security.md) go straight to the processes. Either way
the run completes, every real vehicle is scored in full and nothing else is, every process stays
alive, and each rejection is counted by reason in summary.json.
"""

import json
import subprocess
import time

import numpy as np
import pytest

from bus import messages as m
from bus.config import BusConfig
from bus.mavlink_codec import MavlinkEncoder, StateEstimate
from bus.session import Transport, ZenohBus, await_subscribers
from tests.integration.conftest import ESTIMATES_PER_S, read_summary, swarm_command, wait_for_metrics

pytestmark = pytest.mark.integration
DURATION_S = 150
FLOOD = 10_000
REFUSED = {"v/2/mavlink", "v/1/v2v", "ctl/ack/1", "v/1/status", "v/1/feed", "ctl/clock"}  # by the router, to vehicle-3
ALLOWED = {"v/x/v2v", "v/x/mavlink", "v/3/mavlink", "v/3/v2v", "v/3/status", "ctl/ack/3"}  # reach the processes


def _estimate(vid: int, t_us: int, cov=None) -> StateEstimate:
    return StateEstimate(
        vid,
        t_us,
        np.array([1.0, 2.0, -30.0]),
        0.0,
        np.zeros(3),
        0.0,
        np.eye(6) * 0.5 if cov is None else cov,
        np.eye(6),
    )


def _start(tmp_path, name: str, *extra: str):
    process = subprocess.Popen(
        swarm_command(
            tmp_path, "--vehicles", "3", "--duration", str(DURATION_S), "--seed", "5", "--name", name, *extra
        ),
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    run = tmp_path / name
    wait_for_metrics(run, 5_000)
    handle = json.loads((run / "swarm.json").read_text())
    return process, run, handle["connect"][0]


def _attacker(endpoint: str, user: str | None = None, password: str | None = None) -> ZenohBus:
    # role "groundstation" switches off our own in-process check: only the router decides
    return ZenohBus(
        BusConfig(connect=(endpoint,)), role="groundstation", transport=Transport(user=user, password=password)
    )


def _heard(bus: ZenohBus, key: str):
    """A publisher on ``key`` once this session knows who listens: a zenoh client drops what it
    publishes before that, which would make a hostile message vanish instead of being tested."""
    publisher = bus.publisher(key)
    assert not await_subscribers({key: publisher}, timeout_s=20.0), f"nobody listens on {key}"
    return publisher


def _finish(process) -> str:
    output, _ = process.communicate(timeout=300)
    assert process.returncode == 0, output  # every process alive to the end, a complete run
    return output


def _assert_scored_in_full(summary: dict) -> None:
    assert summary["status"] == "complete"
    assert set(summary["vehicles"]) == {"1", "2", "3"}  # nothing else scored
    for vid in ("1", "2", "3"):
        assert summary["vehicles"][vid]["samples"] == DURATION_S * ESTIMATES_PER_S + 1, vid


def test_a_compromised_vehicle_cannot_speak_for_others_or_stop_the_swarm(tmp_path):
    process, run, endpoint = _start(tmp_path, "secure")
    secrets = run / "secrets"
    key3 = bytes.fromhex((secrets / "vehicle-3.key").read_text().strip())
    signed = MavlinkEncoder(vehicle_id=3, signing_key=key3, link_id=1)  # its own key, another link
    as_two = MavlinkEncoder(vehicle_id=2, signing_key=key3, link_id=1)
    as_nine = MavlinkEncoder(vehicle_id=9, signing_key=key3, link_id=1)
    now = 1_000_000
    with _attacker(endpoint, "vehicle-3", (secrets / "vehicle-3.password").read_text().strip()) as bus:
        publishers = {key: bus.publisher(f"swarm/{key}") for key in REFUSED | ALLOWED}
        # a zenoh client drops what it publishes before it knows who listens: wait, or a hostile
        # message would vanish instead of being tested (the router's refusals may never show one)
        assert not await_subscribers({k: publishers[k] for k in ALLOWED}, timeout_s=20.0)
        await_subscribers({k: publishers[k] for k in REFUSED}, timeout_s=2.0)
        put = lambda key, payload: publishers[key].put(payload)  # noqa: E731

        # speaking for other vehicles: refused by the router
        put("v/2/mavlink", as_two.odometry(_estimate(2, now))), put("v/1/v2v", as_two.odometry(_estimate(1, now)))
        put("ctl/ack/1", b"\x00"), put("v/1/status", b"\x00"), put("v/1/feed", b"\x00"), put("ctl/clock", b"\x00")
        bus.declare_token("swarm/alive/vehicle/1")
        # keys that name no vehicle pass the router; the processes refuse them (bad_key)
        put("v/x/v2v", b"bytes"), put("v/x/mavlink", b"bytes")
        bus.declare_token("swarm/alive/vehicle/\u00b2")
        # hostile but well-formed, on its own keys: reaches the processes
        put("v/3/mavlink", as_two.odometry(_estimate(2, now)))  # as vehicle 2: not 2's signature
        put("v/3/v2v", as_two.odometry(_estimate(2, 200_000)))  # impersonation (vehicles 1, 2)
        put("v/3/status", m.encode(m.VehicleStatus(1, 0, 0, 0, 0.0, 0.0, 0, 0, 0, 0)))  # status as vehicle 1
        put("v/3/mavlink", as_nine.odometry(_estimate(9, now)))  # unknown sysid
        for cov in (
            np.zeros((6, 6)),
            np.diag([1.0, 1.0, 1e-6, 1e-6, 1e-6, 0.0]),
            np.diag([1.0, 1.0, 1e-6, 1e-6, 1e-6, -1.0]),
            np.diag([1e12, 1.0, 1e-6, 1e-6, 1e-6, 1.0]),
        ):
            put("v/3/mavlink", signed.odometry(_estimate(3, now, cov)))  # degenerate x 4
        put("v/3/mavlink", signed.odometry(_estimate(3, 2**50)))  # far future
        put("ctl/ack/3", b"\x93\x01\x02")  # malformed ack
        put("v/3/status", b"\xc1")  # malformed status
        put("v/3/mavlink", b"\xfd" * 100_000), put("v/3/v2v", b"\xfd" * 2_000), put("ctl/ack/3", b"x" * 10_000)
        put("v/3/mavlink", signed.heartbeat()[:-7])  # truncated
        flood = publishers["v/3/mavlink"]
        for k in range(FLOOD):
            flood.put(b"\xfe" + k.to_bytes(4, "little"))
    _finish(process)
    summary = read_summary(run)
    _assert_scored_in_full(summary)
    rejected = summary["rejected"]["by_process"]
    # the bad token is refused twice: when it appears and when it goes
    assert rejected["groundstation"] == {
        "bad_key": 3,
        "bad_signature": 1,
        "impersonation": 1,
        "unknown_sysid": 1,
        "degenerate": 4,
        "stamp_out_of_range": 1,
        "oversized": 1,
        "malformed": FLOOD + 2,
    }
    assert rejected["world"] == {"bad_key": 2, "malformed": 1, "oversized": 1}
    for vid in (1, 2):
        assert rejected[f"vehicle-{vid}"] == {"bad_key": 1, "impersonation": 1, "oversized": 1}
    assert rejected["vehicle-3"] == {"bad_key": 1, "oversized": 1}  # its own key's v2v is not for itself
    assert summary["vehicles"]["3"]["mavlink_rejected"] == FLOOD + 8


def test_the_cases_of_the_issue_are_survived_with_no_filtering_at_all(tmp_path):
    process, run, endpoint = _start(tmp_path, "insecure", "--insecure")
    zero = MavlinkEncoder(vehicle_id=2).odometry(_estimate(2, 1_000_000, np.zeros((6, 6))))
    with _attacker(endpoint) as bus:
        _heard(bus, "swarm/v/x/v2v").put(b"any bytes")
        _heard(bus, "swarm/v/x/mavlink").put(b"any bytes")
        bus.declare_token("swarm/alive/vehicle/\u00b2")
        _heard(bus, "swarm/v/2/mavlink").put(zero)  # degenerate, as vehicle 2
        _heard(bus, "swarm/ctl/ack/\u00b2").put(b"x")
        _heard(bus, "swarm/v/2/feed").put(b"\x00" * 50)  # garbage as the world's feed
        _heard(bus, "swarm/ctl/clock").put(b"\xc1")  # garbage as the clock
        time.sleep(0.5)
    _finish(process)
    summary = read_summary(run)
    _assert_scored_in_full(summary)
    rejected = summary["rejected"]["by_process"]
    assert rejected["groundstation"] == {"bad_key": 3, "degenerate": 1, "malformed": 1}  # + the garbage clock
    assert rejected["world"] == {"bad_key": 3}  # the token twice and the ack
    assert rejected["vehicle-2"]["malformed"] == 2  # its feed and the clock
    assert all(rejected[f"vehicle-{v}"]["bad_key"] == 1 for v in (1, 2, 3))  # v/x/v2v
