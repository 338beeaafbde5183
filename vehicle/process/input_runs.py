"""A sensor batch's high-rate inputs (IMU, wheel odometry) handed to the fusion horizon as runs.

A batch carries some 150 input samples a second. Made into a message each, then a delivery, a
pending entry and a handled message, they were a quarter of a vehicle's time; as runs they are
lists of floats that the fusion horizon applies in the same order (``vehicle.process.fusion``) and the
filter takes as rows (``Filter.handle_row``). Every sample of a batch keeps the place it has in
``SensorBatch.samples``' order (stamp, then the batch's topic order, camera frames last): its
arrival number is the batch's first plus that place, so that it interleaves with the batch's other
samples, and with anything pushed later, exactly as one message at a time would.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from typing import Any

from bus.feed import SensorBatch
from bus.topics import Topic

INPUT_TOPICS = (Topic.IMU, Topic.ODOM)


@dataclass
class InputRun:
    """A batch's input samples (IMU and wheel odometry together) in the batch's order: their stamps
    (us), arrival numbers, (topic, seq) and rows (bus.feed LAYOUT, floats), and, for the rare paths,
    the ``i``-th one as its message; ``blocks``: (topic, first seq, count) of each topic;
    ``next``: the first not yet applied. One run for both topics: the fusion horizon applies the
    gyro and the wheels as they interleave without taking turns through its queue."""

    stamps: list[int]
    arrivals: list[int]
    idents: list[tuple[str, int]]
    rows: list[list[float]]
    message: Callable[[int], Any]
    blocks: list[tuple[str, int, int]]
    next: int = 0


def unpack(batch: SensorBatch, first: int) -> tuple[InputRun | None, list[tuple[int, str, Any]]]:
    """``batch``'s input samples as a run (None when it has none) and its other samples as (arrival
    number, topic, message) in its order, numbered from ``first`` (``FusionHorizon.reserve`` of the
    batch's sample count). Plain Python: a realtime batch holds a few rows, and numpy's per-call cost
    was most of unpacking one."""
    keyed, topics = batch_order(batch)
    stamps, arrivals, idents, rows, others = [], [], [], [], []
    for arrival, (stamp, t, i) in enumerate(keyed, first):
        topic, seq0, block_rows = topics[t]
        if block_rows is None:  # not an input sample
            others.append((arrival, topic, batch.message(topic, i)))
            continue
        stamps.append(stamp)
        arrivals.append(arrival)
        idents.append((topic, seq0 + i))
        rows.append(block_rows[i])
    if not stamps:  # no input samples (a blackout's batch)
        return None, others
    blocks = [(topic, seq0, len(block_rows)) for topic, seq0, block_rows in topics if block_rows is not None]
    return InputRun(stamps, arrivals, idents, rows, partial(_message, batch, idents), blocks), others


def _message(batch: SensorBatch, idents: list[tuple[str, int]], i: int) -> Any:
    """The run's ``i``-th sample (``idents``: the run's (topic, seq)) as its message."""
    topic, seq = idents[i]
    return batch.message(topic, seq - batch.blocks[topic][1])


def batch_order(batch: SensorBatch) -> tuple[list[tuple[int, int, int]], list[tuple[str, int, list | None]]]:
    """Every sample of ``batch`` as (stamp us, topic number, index in its block) in
    ``SensorBatch.samples``' order (by stamp, then the batch's topic order, camera frames last), and
    per topic number (topic, first seq, its rows as lists of floats: None where it is not an input,
    ``Topic.CAMERA`` for the frames)."""
    keyed, topics = [], []
    for topic, (stamps, seq0, rows) in batch.blocks.items():
        keyed += zip(stamps.tolist(), itertools.repeat(len(topics)), itertools.count())
        topics.append((topic, seq0, rows.tolist() if topic in INPUT_TOPICS else None))
    if batch.camera is not None:
        keyed += zip(batch.camera.stamps.tolist(), itertools.repeat(len(topics)), itertools.count())
        topics.append((Topic.CAMERA, batch.camera.seq0, None))
    keyed.sort()  # a block's stamps never decrease: the stable order of the stamps
    return keyed, topics
