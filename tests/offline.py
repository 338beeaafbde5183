"""Run the pure world and vehicle estimator cores together with no bus (for Monte Carlo tests)."""

from __future__ import annotations

import queue

import numpy as np

from bus import feed
from bus import messages as m
from bus.config import SensorSpec, build_config
from sim.world import World
from vehicle.estimators.ekf import UnicycleEkf
from vehicle.gnss_health import GnssHealthSpec


def samples_of(world: World, until_us: int, vehicle_id: int = 1) -> tuple[list[tuple[str, object]], feed.TruthBatch]:
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
    truth = feed.TruthBatch(0, until_us, np.array(stamps, dtype=np.int64), np.array(ids),
                            np.array(rows).reshape(len(stamps), len(ids), feed.TRUTH_WIDTH))
    return samples, truth


def _ekf(spec: SensorSpec, gate_probability: float, kind: str = "ekf", adaptive_window: int = 0) -> UnicycleEkf:
    """The vehicle filter of ``kind`` (ekf or ukf) for vehicle 1 (``adaptive_window``: IAE)."""
    if kind == "ukf":
        from vehicle.estimators.ukf import UnicycleUkf

        return UnicycleUkf(vehicle_id=1, spec=spec, gate_probability=gate_probability, altitude_m=30.0,
                           adaptive_window=adaptive_window)
    return UnicycleEkf(vehicle_id=1, spec=spec, gate_probability=gate_probability, altitude_m=30.0,
                       adaptive_window=adaptive_window)


def _run(world: World, estimators: list[UnicycleEkf], duration_s: float, every_us: int, on_truth) -> None:
    """Feed the estimators (each the same samples) cycle by cycle (50 Hz) and call
    ``on_truth(stamp, pose)`` every ``every_us`` while any of them is initialized."""
    step_us, left = 1_000_000, []
    for start in range(0, round(duration_s * 1e6), step_us):
        end = min(start + step_us - 1, round(duration_s * 1e6))
        samples, truth = samples_of(world, end)
        samples = left + samples
        truth_at = {int(s): truth.rows[k, 0, :3] for k, s in enumerate(truth.stamps_us)}
        i = 0
        for t in range(start, end + 1, 20_000):
            first = i
            while i < len(samples) and samples[i][1].stamp_us <= t:
                i += 1
            for estimator in estimators:
                for sample in samples[first:i]:
                    estimator.handle(*sample)
                estimator.cycle(t)
            if t % every_us == 0 and any(e.initialized for e in estimators):
                on_truth(t, truth_at[t])
        left = samples[i:]


def pose_nees_series(seed: int, *, duration_s: float, trajectory: str, every_us: int = 1_000_000,
                     estimator_spec: SensorSpec | None = None, world_sensors: SensorSpec | None = None,
                     kind: str = "ekf", world: dict | None = None, adaptive_window: int = 0,
                     estimator_out: list | None = None) -> tuple[np.ndarray, np.ndarray]:
    """NEES over [x, y, yaw] and position error (m) of one vehicle, sampled every ``every_us``.

    ``world_sensors`` overrides what the world simulates, ``world`` adds to the world section (e.g.
    its sensor_truth); ``estimator_spec`` what the filter assumes; ``kind`` picks the filter (ekf or
    ukf), ``adaptive_window`` turns IAE on; ``estimator_out`` receives the filter at the end.
    """
    filters = [{"estimator_spec": estimator_spec, "kind": kind, "adaptive_window": adaptive_window}]
    return nees_series_of_filters(seed, filters, duration_s=duration_s, trajectory=trajectory, every_us=every_us,
                                  world_sensors=world_sensors, world=world, estimators_out=estimator_out)[0]


def nees_series_of_filters(seed: int, filters: list[dict], *, duration_s: float, trajectory: str,
                           every_us: int = 1_000_000, world_sensors: SensorSpec | None = None,
                           world: dict | None = None, estimators_out: list | None = None
                           ) -> list[tuple[np.ndarray, np.ndarray]]:
    """:func:`pose_nees_series` of several filters on one world (one simulation, each filter fed the
    same samples): ``filters`` holds each one's ``estimator_spec``, ``kind`` and ``adaptive_window``
    (any left out: the defaults); one (NEES, position error) pair per filter, in order."""
    sensors = (world_sensors or SensorSpec()).model_dump()
    config = build_config({"world": {"vehicles": 1, "seed": seed, "trajectories": [trajectory], **(world or {})},
                           "sensors": sensors})
    estimators = [_ekf(f.get("estimator_spec") or config.sensors, config.vehicle.gate_probability,
                       f.get("kind", "ekf"), f.get("adaptive_window", 0)) for f in filters]
    if estimators_out is not None:
        estimators_out.extend(estimators)
    nees: list[list[float]] = [[] for _ in filters]
    errors: list[list[float]] = [[] for _ in filters]

    def score(t: int, pose: np.ndarray) -> None:
        for estimator, its_nees, its_errors in zip(estimators, nees, errors):
            if not estimator.initialized:
                continue
            d = estimator.x[:3] - pose
            d[2] = (d[2] + np.pi) % (2 * np.pi) - np.pi
            its_nees.append(float(d @ np.linalg.solve(estimator.P[:3, :3], d)))
            its_errors.append(float(np.hypot(d[0], d[1])))

    _run(World(config), estimators, duration_s + 1e-6, every_us, score)
    return [(np.array(n), np.array(e)) for n, e in zip(nees, errors)]


def gnss_fault_run(seed: int, *, duration_s: float, faults: list[dict], monitor: bool = True,
                   every_us: int = 200_000) -> dict[str, np.ndarray]:
    """One vehicle on its circle with world ``faults``: time (s), position error (m) and GNSS health,
    sampled every ``every_us``. ``monitor=False`` fuses every fix that passes the gate (no health checks)."""
    config = build_config({"world": {"vehicles": 1, "seed": seed, "trajectories": ["circle"]}, "faults": faults})
    estimator = _ekf(config.sensors, config.vehicle.gate_probability)
    if not monitor:
        estimator.gnss_health.spec = GnssHealthSpec(mean_gate_probability=1.0 - 1e-300, unhealthy_after_s=1e9,
                                                    fix_timeout_s=1e9)
    t, errors, healthy = [], [], []

    def score(stamp: int, pose: np.ndarray) -> None:
        t.append(stamp * 1e-6)
        errors.append(float(np.hypot(*(estimator.x[:2] - pose[:2]))))
        healthy.append(estimator.gnss_health.healthy)

    _run(World(config), [estimator], duration_s, every_us, score)
    return {"t_s": np.array(t), "error_m": np.array(errors), "healthy": np.array(healthy)}


def swarm_in_memory(config, *, sample_every_us: int = 200_000) -> dict[int, dict[str, np.ndarray]]:
    """The real vehicle nodes (V2V, link faults, fusion horizon) and the world in one process over
    the in-memory bus, in lockstep. Returns per vehicle: t_s, position error (m), pose NEES and its
    position (2 dof) and heading (1 dof) parts of the published estimates, sampled every
    ``sample_every_us``."""
    from bus.mavlink_codec import MavlinkDecoder, StateEstimate, split_frames
    from bus.memory import MemoryHub
    from groundstation.scoring import score
    from sim.node import WorldNode
    from vehicle.node import VehicleNode

    hub = MemoryHub(config.bus.prefix)
    world_bus, keys = hub.connect("world"), None
    world = WorldNode(world_bus, config)
    keys = world_bus.keys
    listener = hub.connect("groundstation")
    estimates: queue.SimpleQueue = queue.SimpleQueue()
    listener.subscribe(f"{keys.prefix}/v/*/mavlink", estimates)
    nodes = [VehicleNode(hub.connect("vehicle"), config.for_vehicle(), vid) for vid in world.world.vehicle_ids()]
    for node in nodes:
        node.join()
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
        for node in nodes:
            tick = None
            while not node.mailbox.empty():
                tick = node.take(node.mailbox.get_nowait()) or tick
            for t_us in node.cycles_due(prepared.stamp_us):
                node.cycle(t_us)
            node.outbound.flush()
            v2v_sent[node.vehicle_id] = node.outbound.v2v_sent
    decoder, out = MavlinkDecoder(), {}
    while not estimates.empty():
        for frame in split_frames(estimates.get().payload)[0]:
            est = decoder.decode(frame)
            if isinstance(est, StateEstimate) and est.time_usec % sample_every_us == 0:
                s = score(est, truth[(est.vehicle_id, est.time_usec)])
                e, cov = s.error_m, s.pose_covariance
                out.setdefault(est.vehicle_id, []).append((est.time_usec * 1e-6, s.position_error_m, s.nees,
                                                           float(e[:2] @ np.linalg.solve(cov[:2, :2], e[:2])),
                                                           float(e[2] ** 2 / cov[2, 2])))
    names = ("t_s", "error_m", "nees", "nees_position", "nees_heading")
    return {vid: dict(zip(names, map(np.array, zip(*rows)))) for vid, rows in out.items()}


def replay_in_memory(config, data, *, every_us: int = 1_000_000, estimators: dict | None = None) -> dict[int, np.ndarray]:
    """A data-set replay (sim.replay) with every vehicle's estimator in this process, no bus: per
    vehicle, rows [t us, position error m, pose NEES] every ``every_us`` where truth exists.
    ``estimators`` replaces the configured ones (vehicle id -> estimator)."""
    from sim.replay import ReplayWorld
    from vehicle.estimators import get_estimator

    world = ReplayWorld(config, data)
    vehicle_config = config.for_vehicle()
    estimators = estimators or {vid: get_estimator(vehicle_config, vid) for vid in world.vehicle_ids()}
    tick_us, rows = 20_000, {vid: [] for vid in estimators}
    for tick in range(round(config.clock.duration_s * 1e6) // tick_us + 1):
        t = tick * tick_us
        out = world.advance(t)
        for vid, estimator in estimators.items():
            for topic, msg in feed.SensorBatch(vid, tick, t, out.blocks(vid)).samples():
                estimator.handle(topic, msg)
            estimator.cycle(t)
            truth = out.truth[-1, vid - 1, :3] if len(out.truth_stamps) and out.truth_stamps[-1] == t else None
            if t % every_us == 0 and estimator.initialized and truth is not None and np.isfinite(truth[0]):
                d = estimator.x[:3] - truth
                d[2] = (d[2] + np.pi) % (2 * np.pi) - np.pi
                rows[vid].append([t, np.hypot(d[0], d[1]), d @ np.linalg.solve(estimator.P[:3, :3], d)])
    return {vid: np.array(r).reshape(-1, 3) for vid, r in rows.items()}
