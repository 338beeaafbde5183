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
    """Samples of one input ``topic`` in stamp order: their stamps (us), arrival numbers, rows (bus.feed
    LAYOUT, floats) and, for the rare paths, the ``i``-th one as its message; ``next``: the first not
    yet applied."""

    topic: str
    stamps: list[int]
    arrivals: list[int]
    rows: list[list[float]]
    message: Callable[[int], Any]
    seq0: int
    next: int = 0


def unpack(batch: SensorBatch, first: int) -> tuple[list[InputRun], list[tuple[int, str, Any]]]:
    """``batch``'s input samples as runs and its other samples as (arrival number, topic, message) in
    its order, numbered from ``first`` (``FusionHorizon.reserve`` of the batch's sample count)."""
    places, others = batch_order(batch)
    runs = []
    for topic, place in places.items():
        stamps, seq0, rows = batch.blocks[topic]
        message = partial(batch.message, topic)
        runs.append(InputRun(topic, stamps.tolist(), (place + first).tolist(), rows.tolist(), message, seq0))
    return runs, [(first + p, topic, batch.message(topic, i)) for p, topic, i in others]


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
