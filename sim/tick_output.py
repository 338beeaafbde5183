"""What the world process sends: the world it runs (simulated, or a recorded data set replayed), and
one clock tick's output encoded, every vehicle's sensor batch and the truth (computed a tick ahead,
while the vehicles work: sim.node)."""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bus import feed
from bus.config import SwarmConfig
from bus.keys import KeySpace
from sim.world import World

log = logging.getLogger("swarmloc.world")


@dataclass(frozen=True)
class EncodedTick:
    """One tick's output, encoded: (key, payload) of every vehicle's batch, and the truth batch."""

    tick: int
    stamp_us: int
    batches: list[tuple[str, bytes]]
    truth: bytes


def make_world(config: SwarmConfig) -> World:
    """The simulated world, or the replay of a recorded data set (``config.replay``)."""
    if config.replay is None:
        return World(config)
    from sim.mrclam import load_mrclam
    from sim.replay import ReplayWorld

    data = load_mrclam(Path(config.replay.dataset))
    world = ReplayWorld(config, data)
    log.info(
        "replaying robots %s of %s: %d sightings of unknown barcodes and %d of robots not replayed skipped",
        list(config.replay.robots),
        config.replay.dataset,
        sum(data.robots[r].unknown_barcodes for r in config.replay.robots),
        world.skipped_sightings,
    )
    return world


def encode_tick(world: World, keys: KeySpace, tick: int, stamp_us: int, *, addressed_v2v: bool) -> EncodedTick:
    """Advance ``world`` to ``stamp_us`` and encode what it measured for clock tick ``tick``: each
    vehicle's batch names who ranges it when ``addressed_v2v`` (bus.feed.SensorBatch.listeners), the
    truth batch the ranging pairs either way."""
    out = world.advance(stamp_us)
    listeners = out.listeners() if addressed_v2v else None
    batches = [
        (
            keys.feed(vid),
            feed.encode_batch(
                feed.SensorBatch(
                    vid,
                    tick,
                    stamp_us,
                    out.blocks(vid),
                    out.camera(vid),
                    None if listeners is None else listeners.get(vid, ()),
                )
            ),
        )
        for vid in world.vehicle_ids()
    ]
    ids = world.vehicle_ids()
    rows = np.array(out.truth).reshape(len(out.truth_stamps), len(ids), feed.TRUTH_WIDTH)
    ranged = out.listeners() if listeners is None else listeners
    pairs = np.array([(o, t) for t, observers in ranged.items() for o in observers], np.int64).reshape(-1, 2)
    truth = feed.TruthBatch(tick, stamp_us, np.array(out.truth_stamps, dtype=np.int64), np.array(ids), rows, pairs)
    return EncodedTick(tick, stamp_us, batches, feed.encode_truth(truth))
