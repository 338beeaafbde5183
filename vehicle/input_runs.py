"""A sensor batch's high-rate inputs (IMU, wheel odometry) handed to the fusion horizon as runs.

A batch carries some 150 input samples a second. Made into a message each, then a delivery, a
pending entry and a handled message, they were a quarter of a vehicle's time; as runs they are
lists of floats that the fusion horizon applies in the same order (``vehicle.fusion``) and the
filter takes as rows (``Filter.handle_row``). Every sample of a batch keeps the place it has in
``SensorBatch.samples``' order (stamp, then the batch's topic order, camera frames last): its
arrival number is the batch's first plus that place, so that it interleaves with the batch's other
samples, and with anything pushed later, exactly as one message at a time would.
"""

from __future__ import annotations

import itertools
import operator
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from typing import Any

import numpy as np

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
    batch's sample count)."""
    places, others = batch_order(batch)
    others = [(first + p, topic, batch.message(topic, i)) for p, topic, i in others]
    if not sum(len(place) for place in places.values()):  # no input samples (a blackout's batch)
        return None, others
    idents, rows, blocks = [], [], []
    for topic, place in places.items():
        stamps, seq0, block_rows = batch.blocks[topic]
        n = len(place)
        idents += zip(itertools.repeat(topic), range(seq0, seq0 + n))
        rows += block_rows.tolist()
        blocks.append((topic, seq0, n))
    place = np.concatenate(list(places.values()))
    order = np.argsort(place, kind="stable").tolist()  # the batch's order: by stamp, then topic
    stamps = np.concatenate([batch.blocks[t][0] for t in places])
    pick = operator.itemgetter(*order) if len(order) > 1 else (lambda seq: (seq[order[0]],))  # a tuple always
    idents = list(pick(idents))
    run = InputRun(
        stamps[order].tolist(),
        (place[order] + first).tolist(),
        idents,
        list(pick(rows)),
        partial(_message, batch, idents),
        blocks,
    )
    return run, others


def _message(batch: SensorBatch, idents: list[tuple[str, int]], i: int) -> Any:
    """The run's ``i``-th sample (``idents``: the run's (topic, seq)) as its message."""
    topic, seq = idents[i]
    return batch.message(topic, seq - batch.blocks[topic][1])


def batch_order(batch: SensorBatch) -> tuple[dict[str, np.ndarray], list[tuple[int, str, int]]]:
    """The place of every sample of each input topic of ``batch`` (k,) in ``SensorBatch.samples``'
    order, and the other samples as (place, topic, index), in that order (``Topic.CAMERA`` for the
    camera frames)."""
    topics = list(batch.blocks) + ([Topic.CAMERA] if batch.camera is not None else [])
    stamps = [batch.blocks[t][0] for t in batch.blocks] + ([batch.camera.stamps] if batch.camera is not None else [])
    if not stamps:
        return {}, []
    order = np.argsort(np.concatenate(stamps), kind="stable")
    place = np.empty_like(order)
    place[order] = np.arange(len(order))
    runs, others, start = {}, [], 0
    for topic, block in zip(topics, stamps):
        places = place[start : start + len(block)]
        start += len(block)
        if topic in INPUT_TOPICS:
            runs[topic] = places
        else:
            others += [(p, topic, i) for i, p in enumerate(places.tolist())]
    others.sort()
    return runs, others
