"""Run the pure world and vehicle estimator cores together with no bus (for Monte Carlo tests)."""

from __future__ import annotations

import queue

import numpy as np

from bus import messages as m
from bus.config import SensorSpec, build_config
from bus.keys import KeySpace
from sim.world import World
from vehicle.estimator import VehicleEstimator
from vehicle.gnss_health import GnssHealthSpec

TYPES = {"imu": m.ImuSample, "odom": m.WheelOdometry, "gnss": m.GnssFix, "prior": m.PosePrior, "truth": m.Truth}


def pose_nees_series(seed: int, *, duration_s: float, trajectory: str, every_us: int = 1_000_000,
                     estimator_spec: SensorSpec | None = None,
                     world_sensors: SensorSpec | None = None) -> tuple[np.ndarray, np.ndarray]:
    """NEES over [x, y, yaw] and position error (m) of one vehicle, sampled every ``every_us``.

    ``world_sensors`` overrides what the world simulates; ``estimator_spec`` what the filter assumes.
    """
    sensors = (world_sensors or SensorSpec()).model_dump()
    config = build_config({"world": {"vehicles": 1, "seed": seed, "trajectories": [trajectory]}, "sensors": sensors})
    world, keys = World(config), KeySpace()
    estimator = VehicleEstimator(vehicle_id=1, spec=estimator_spec or config.sensors,
                                 gate_probability=config.vehicle.gate_probability, altitude_m=30.0)
    nees, errors = [], []
    for key, payload in world.advance(round(duration_s * 1e6)):
        msg = m.decode(TYPES[keys.topic_of(key)], payload)
        if not isinstance(msg, m.Truth):
            estimator.handle(msg)
        elif estimator.initialized and msg.stamp_us % every_us == 0:
            x, P = estimator.predicted(msg.stamp_us)
            d = x[:3] - msg.pose
            d[2] = (d[2] + np.pi) % (2 * np.pi) - np.pi
            nees.append(float(d @ np.linalg.solve(P[:3, :3], d)))
            errors.append(float(np.hypot(d[0], d[1])))
    return np.array(nees), np.array(errors)


def gnss_fault_run(seed: int, *, duration_s: float, faults: list[dict], monitor: bool = True,
                   every_us: int = 200_000) -> dict[str, np.ndarray]:
    """One vehicle on its circle with world ``faults``: time (s), position error (m) and GNSS health,
    sampled every ``every_us``. ``monitor=False`` fuses every fix that passes the gate (no health checks)."""
    config = build_config({"world": {"vehicles": 1, "seed": seed, "trajectories": ["circle"]}, "faults": faults})
    world, keys = World(config), KeySpace()
    estimator = VehicleEstimator(vehicle_id=1, spec=config.sensors, gate_probability=config.vehicle.gate_probability,
                                 altitude_m=30.0)
    if not monitor:
        estimator.gnss_health.spec = GnssHealthSpec(mean_gate_probability=1.0 - 1e-300, unhealthy_after_s=1e9,
                                                    fix_timeout_s=1e9)
    t, errors, healthy = [], [], []
    for key, payload in world.advance(round(duration_s * 1e6)):
        msg = m.decode(TYPES[keys.topic_of(key)], payload)
        if not isinstance(msg, m.Truth):
            estimator.handle(msg)
        elif estimator.initialized and msg.stamp_us % every_us == 0:
            estimator.tick(msg.stamp_us)
            x, _ = estimator.predicted(msg.stamp_us)
            t.append(msg.stamp_us * 1e-6)
            errors.append(float(np.hypot(*(x[:2] - msg.pose[:2]))))
            healthy.append(estimator.gnss_health.healthy)
    return {"t_s": np.array(t), "error_m": np.array(errors), "healthy": np.array(healthy)}


def swarm_in_memory(config, *, sample_every_us: int = 200_000) -> dict[int, dict[str, np.ndarray]]:
    """The real vehicle nodes (V2V, link faults, fusion horizon) and the world in one process over
    the in-memory bus, in lockstep. Returns per vehicle: t_s, position error (m) and pose NEES of the
    published estimates, sampled every ``sample_every_us``."""
    from bus.mavlink_codec import MavlinkDecoder, StateEstimate
    from bus.memory import MemoryHub
    from groundstation.scoring import score
    from vehicle.node import VehicleNode

    hub = MemoryHub(config.bus.prefix)
    world, keys, world_bus = World(config), KeySpace(config.bus.prefix), hub.connect("world")
    listener = hub.connect("groundstation")
    estimates: queue.SimpleQueue = queue.SimpleQueue()
    listener.subscribe(f"{keys.prefix}/v/*/mavlink", estimates)
    nodes = [VehicleNode(hub.connect("vehicle"), config, vid) for vid in world.vehicle_ids()]
    truth: dict[tuple[int, int], np.ndarray] = {}
    tick_us = round(config.clock.tick_s * 1e6)
    for k in range(round(config.clock.duration_s * 1e6) // tick_us + 1):
        stamp = k * tick_us
        for key, payload in world.advance(stamp):
            if key.endswith("/truth"):
                t = m.decode(m.Truth, payload)
                truth[(t.vehicle_id, t.stamp_us)] = t.pose
            else:
                world_bus.publisher(key).put(payload)
        world_bus.publisher(keys.clock()).put(m.encode(m.ClockTick(k, stamp, 0, False, world.published(),
                                                                   world.comm_jammed(stamp))))
        for node in nodes:
            while not node.inbox.empty():
                node.take(node.inbox.get())
            for t_us in node.cycles_due(stamp):
                node.cycle(t_us)
    decoder, out = MavlinkDecoder(), {}
    while not estimates.empty():
        est = decoder.decode(estimates.get().payload)
        if isinstance(est, StateEstimate) and est.time_usec % sample_every_us == 0:
            s = score(est, truth[(est.vehicle_id, est.time_usec)])
            out.setdefault(est.vehicle_id, []).append((est.time_usec * 1e-6, s.position_error_m, s.nees))
    return {vid: dict(zip(("t_s", "error_m", "nees"), map(np.array, zip(*rows)))) for vid, rows in out.items()}
