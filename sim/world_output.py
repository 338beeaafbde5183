"""What the world measured over one advance (sim.world): the rows of each vehicle's topics, their
high-rate streams, the truth, and the ranging pairs; as the feed's blocks of one vehicle, in the order
a step emits them."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from bus.feed import CameraBlock
from bus.sensors import BY_TOPIC
from bus.topics import Topic

# within a step: the built-in feeds, then the sensors added by the recipe (bus.sensors)
EMITTED = (Topic.PRIOR, Topic.IMU, Topic.ODOM, Topic.GNSS, Topic.CAMERA, Topic.RANGING, *BY_TOPIC)


@dataclass
class TickOutput:
    """What the world measured over one advance: ``rows[vid][topic]`` is a list of (stamp_us, seq,
    row (w,)) of the topics measured one vehicle at a time, ``streams[vid][topic]`` (stamps (k,),
    first seq, rows (k, w)) of those measured for every vehicle at once (IMU, wheel odometry);
    ``truth_stamps`` (k,) and ``truth`` (k, N, 5) rows [x, y, theta, speed, yaw rate]."""

    rows: dict[int, dict[str, list[tuple[int, int, np.ndarray]]]]
    truth_stamps: list[int]
    truth: list[np.ndarray]
    streams: dict[int, dict[str, tuple[np.ndarray, int, np.ndarray]]] = field(default_factory=dict)

    def blocks(self, vehicle_id: int) -> dict[str, tuple[np.ndarray, int, np.ndarray]]:
        """The bus.feed blocks of one vehicle: topic -> (stamps (k,), first seq, rows (k, w)), in the
        order a step emits them (``EMITTED``) from the earliest first stamp on."""
        out = dict(self.streams.get(vehicle_id, {}))
        for topic, samples in self.rows.get(vehicle_id, {}).items():
            if samples and topic != Topic.CAMERA:
                out[topic] = (
                    np.array([s[0] for s in samples], dtype=np.int64),
                    samples[0][1],
                    np.array([s[2] for s in samples], dtype=np.float64),
                )
        return dict(sorted(out.items(), key=lambda item: (int(item[1][0][0]), EMITTED.index(item[0]))))

    def listeners(self) -> dict[int, tuple[int, ...]]:
        """vehicle id -> the vehicles that ranged it in this advance (sorted): those that pair its
        broadcasts of the advance's epochs with a measurement; a vehicle nobody ranged is absent."""
        out: dict[int, set[int]] = {}
        for observer, topics in self.rows.items():
            for _, _, row in topics.get(Topic.RANGING, ()):
                out.setdefault(int(row[0]), set()).add(observer)
        return {target: tuple(sorted(observers)) for target, observers in out.items()}

    def camera(self, vehicle_id: int) -> CameraBlock | None:
        """The vehicle's camera frames as a bus.feed block (None: no frame in this advance)."""
        frames = self.rows.get(vehicle_id, {}).get(Topic.CAMERA)
        if not frames:
            return None
        return CameraBlock(
            np.array([f[0] for f in frames], dtype=np.int64),
            frames[0][1],
            np.array([f[2][0] for f in frames]),
            np.stack([f[2][1] for f in frames]),
        )
