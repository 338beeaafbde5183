"""Link quality of each vehicle's MAVLink stream as a ground station sees it, from the 8-bit
sequence numbers every MAVLink frame carries (as QGroundControl and MAVProxy count it)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class StreamQuality:
    received: int = 0
    lost: int = 0
    duplicates: int = 0
    reordered: int = 0
    last_seq: int | None = None

    def see(self, seq: int) -> None:
        """One frame with sequence number ``seq`` (0-255, wrapping) has arrived."""
        self.received += 1
        if self.last_seq is None:
            self.last_seq = seq
            return
        step = (seq - self.last_seq) % 256
        if step == 0:
            self.duplicates += 1
        elif step < 128:
            self.lost += step - 1
            self.last_seq = seq
        else:  # from the past: a frame counted as lost has arrived late after all
            self.reordered += 1
            self.lost = max(0, self.lost - 1)

    @property
    def loss_rate(self) -> float:
        total = self.received - self.duplicates + self.lost
        return self.lost / total if total else 0.0

    def as_dict(self) -> dict:
        return {
            "received": self.received,
            "lost": self.lost,
            "duplicates": self.duplicates,
            "reordered": self.reordered,
            "loss_rate": round(self.loss_rate, 6),
        }
