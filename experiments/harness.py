"""The in-process harness: the runs the tests, the benchmarks and the centralized reference share,
built on launch.in_process (the pure world, or a data-set replay, feeding estimators with no bus, in
stamp order, cycle by cycle at the vehicles' loop rate)."""

from __future__ import annotations

import queue
from collections.abc import Iterable
from typing import Any

import numpy as np

from bus import feed
from bus.config import SensorSpec, build_config
from launch.in_process import PERIOD_US, Listener, pose_score, run, samples
from launch.in_process import replay_in_memory as replay_in_memory  # the tests' and figures' name for it
from vehicle.estimators import build_estimator
from vehicle.estimators.filter import Filter
from vehicle.estimators.gnss_health import GnssHealthSpec


def samples_of(world: Any, until_us: int, vehicle_id: int = 1) -> tuple[list[tuple[str, object]], feed.TruthBatch]:
    """Advance ``world`` to ``until_us``: one vehicle's samples (topic, message) in stamp order, and
    the truth of every vehicle, both through the wire format (one batch per second)."""
    samples, stamps, rows, ids = [], [], [], world.vehicle_ids()
    end = world.now_us
    while end < until_us:
        end = min(until_us, end + 1_000_000)
        out = world.advance(end)
        batch = feed.encode_batch(feed.SensorBatch(vehicle_id, 0, end, out.blocks(vehicle_id)))
        samples += feed.decode_batch(batch).samples()
        stamps += out.truth_stamps
        rows += out.truth
    truth = feed.TruthBatch(
        0,
        until_us,
        np.array(stamps, dtype=np.int64),
        np.array(ids),
        np.array(rows).reshape(len(stamps), len(ids), feed.TRUTH_WIDTH),
    )
    return samples, truth


def vehicle_filter(spec: SensorSpec, gate_probability: float, kind: str = "ekf", adaptive_window: int = 0) -> Filter:
    """Vehicle 1's filter of ``kind`` (an estimator the registry names: ekf, ukf); ``adaptive_window``: IAE."""
    arguments = {"spec": spec, "gate_probability": gate_probability, "adaptive_window": adaptive_window}
    return build_estimator(kind, vehicle_id=1, **arguments)


def nees_series_of_filters(
    seed: int,
    filters: list[dict],
    *,
    duration_s: float,
    trajectory: str,
    every_us: int = 1_000_000,
    world_sensors: SensorSpec | None = None,
    world: dict | None = None,
    estimators_out: list | None = None,
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Pose NEES and position error (m) of vehicle 1's filters on one simulated world, sampled every
    ``every_us``: ``filters`` holds each one's ``estimator_spec`` (what it assumes), ``kind`` (ekf,
    ukf) and ``adaptive_window`` (IAE); ``world_sensors`` overrides what the world simulates, ``world``
    adds to its section (e.g. its sensor_truth); ``estimators_out`` receives the filters."""
    from sim.world import World

    sensors = (world_sensors or SensorSpec()).model_dump()
    config = build_config(
        {"world": {"vehicles": 1, "seed": seed, "trajectories": [trajectory], **(world or {})}, "sensors": sensors}
    )
    estimators = [
        vehicle_filter(
            f.get("estimator_spec") or config.sensors,
            config.vehicle.gate_probability,
            f.get("kind", "ekf"),
            f.get("adaptive_window", 0),
        )
        for f in filters
    ]
    if estimators_out is not None:
        estimators_out.extend(estimators)
    scores: list[list[tuple[float, float]]] = [[] for _ in filters]

    def score(t_us: int, truth: np.ndarray | None) -> None:
        if t_us % every_us or not any(e.initialized for e in estimators):
            return
        for estimator, its_scores in zip(estimators, scores):
            if estimator.initialized:
                its_scores.append(pose_score(estimator, truth[0, :3]))

    listeners = [Listener((1,), e) for e in estimators]
    run(World(config), listeners, end_us=round(duration_s * 1e6), wire=True, on_cycle=score)
    return [(np.array([n for n, _ in s]), np.array([e for _, e in s])) for s in scores]


def pose_nees_series(
    seed: int,
    *,
    duration_s: float,
    trajectory: str,
    every_us: int = 1_000_000,
    estimator_spec: SensorSpec | None = None,
    world_sensors: SensorSpec | None = None,
    kind: str = "ekf",
    world: dict | None = None,
    adaptive_window: int = 0,
    estimator_out: list | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`nees_series_of_filters` of one filter."""
    filters = [{"estimator_spec": estimator_spec, "kind": kind, "adaptive_window": adaptive_window}]
    return nees_series_of_filters(
        seed,
        filters,
        duration_s=duration_s,
        trajectory=trajectory,
        every_us=every_us,
        world_sensors=world_sensors,
        world=world,
        estimators_out=estimator_out,
    )[0]


def gnss_fault_run(
    seed: int, *, duration_s: float, faults: list[dict], monitor: bool = True, every_us: int = 200_000
) -> dict[str, np.ndarray]:
    """One vehicle on its circle with world ``faults``: time (s), position error (m) and GNSS health,
    sampled every ``every_us``. ``monitor=False`` fuses every fix that passes the gate (no health checks)."""
    from sim.world import World

    config = build_config({"world": {"vehicles": 1, "seed": seed, "trajectories": ["circle"]}, "faults": faults})
    estimator = vehicle_filter(config.sensors, config.vehicle.gate_probability)
    if not monitor:
        estimator.state.gnss_health.spec = GnssHealthSpec(
            mean_gate_probability=1.0 - 1e-300, unhealthy_after_s=1e9, fix_timeout_s=1e9
        )
    t, errors, healthy = [], [], []

    def score(t_us: int, truth: np.ndarray | None) -> None:
        if t_us % every_us or not estimator.initialized:
            return
        t.append(t_us * 1e-6)
        errors.append(float(np.hypot(*(estimator.state.x[:2] - truth[0, :2]))))
        healthy.append(estimator.state.gnss_health.healthy)

    run(World(config), [Listener((1,), estimator)], end_us=round(duration_s * 1e6) - 1, wire=True, on_cycle=score)
    return {"t_s": np.array(t), "error_m": np.array(errors), "healthy": np.array(healthy)}


def swarm_in_memory(
    config, *, sample_every_us: int = 200_000, nodes_out: list | None = None
) -> dict[int, dict[str, np.ndarray]]:
    """The real vehicle nodes (V2V, link faults, fusion horizon) and the world in one process over
    the in-memory bus, in lockstep, stepped cycle by cycle across the nodes (a vehicle process waits
    for the broadcasts its cycle pairs with; one node run through a whole tick first would miss the
    others' broadcasts of that tick). Returns per vehicle: t_s, position error (m), pose NEES and its
    position (2 dof) and heading (1 dof) parts of the published estimates, sampled every
    ``sample_every_us``; ``nodes_out`` receives the vehicle nodes."""
    from bus.mavlink_codec import MavlinkDecoder, StateEstimate, split_frames
    from bus.memory import MemoryHub
    from groundstation.scoring import score
    from sim.node import WorldNode
    from vehicle.process.node import VehicleNode

    hub = MemoryHub(config.bus.prefix)
    world_bus, keys = hub.connect("world"), None
    world = WorldNode(world_bus, config)
    keys = world_bus.keys
    listener = hub.connect("groundstation")
    estimates: queue.SimpleQueue = queue.SimpleQueue()
    listener.subscribe(keys.mavlink("*"), estimates)
    nodes = [VehicleNode(hub.connect("vehicle"), config.for_vehicle(), vid) for vid in world.world.vehicle_ids()]
    for node in nodes:
        node.join()
    if nodes_out is not None:
        nodes_out.extend(nodes)
    truth: dict[tuple[int, int], np.ndarray] = {}
    v2v_sent = {}
    for k in range(world.final_tick + 1):
        prepared = world.prepare(k)
        batch = feed.decode_truth(prepared.truth)
        for i, stamp in enumerate(batch.stamps_us.tolist()):
            for n, vid in enumerate(batch.vehicle_ids.tolist()):
                truth[(vid, stamp)] = batch.rows[i, n, :3]
        for vid, sent in v2v_sent.items():
            world.members.on_v2v_count(vid, sent)
        world.send(prepared, final=False)
        due = [node.cycles_due(prepared.stamp_us) for node in nodes]
        for t_us in sorted(set().union(*due)):  # cycle by cycle, as the processes' V2V wait makes them
            for node, cycles in zip(nodes, due, strict=True):
                while not node.mailbox.empty():
                    node.take(node.mailbox.get_nowait())
                if t_us in cycles:
                    node.cycle(t_us)
                    node.report(t_us)
        for node in nodes:
            node.outbound.flush()
            v2v_sent[node.vehicle_id] = node.outbound.v2v_sent
    decoder, out = MavlinkDecoder(), {}
    while not estimates.empty():
        for frame in split_frames(estimates.get().payload)[0]:
            est = decoder.decode(frame)
            if isinstance(est, StateEstimate) and est.time_usec % sample_every_us == 0:
                s = score(est, truth[(est.vehicle_id, est.time_usec)])
                e, cov = s.error_m, s.pose_covariance
                out.setdefault(est.vehicle_id, []).append(
                    (
                        est.time_usec * 1e-6,
                        s.position_error_m,
                        s.nees,
                        float(e[:2] @ np.linalg.solve(cov[:2, :2], e[:2])),
                        float(e[2] ** 2 / cov[2, 2]),
                    )
                )
    names = ("t_s", "error_m", "nees", "nees_position", "nees_heading")
    return {vid: dict(zip(names, map(np.array, zip(*rows)))) for vid, rows in out.items()}


def vehicle_feed(config, vehicle_id: int = 1) -> list[tuple[Any, Any]]:
    """Every sample the world measures for one vehicle over ``config.clock.duration_s``, camera frames
    included, in stamp order, as (topic, message) pairs: what the vehicle process unpacks."""
    from sim.world import World

    end_us = round(config.clock.duration_s * 1e6)
    return samples(World(config).advance(end_us), vehicle_id, end_us, camera=True)


def feed_filter(f: Filter, stream: Iterable[tuple[Any, Any]], *, period_us: int = PERIOD_US) -> None:
    """Hand a filter a recorded stream (topic, message) in stamp order, cycling every ``period_us``."""
    t_us = 0
    for _, msg in stream:
        while t_us < msg.stamp_us:
            f.cycle(t_us)
            t_us += period_us
        f.handle(msg)
