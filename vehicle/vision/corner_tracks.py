"""Corners followed from frame to frame: pyramidal Lucas-Kanade (OpenCV's ``calcOpticalFlowPyrLK``)
with the forward-backward check of Kalal, Mikolajczyk and Matas (ICPR 2010): a corner is followed into
the next frame, then back, and kept only where it comes back within ``fb_px`` of where it started;
a track whose patch no longer looks like its first (NCC below ``min_ncc``) is let go, so a track
cannot drift onto other texture a little at a time. New corners (the detector's, strongest first) join
away from the live tracks, up to ``max_tracks``.

Two frames apart by a long baseline are then paired through the tracks they share (``pairs``): each
pair's pixels were followed over small steps, where the search is short and the match unambiguous,
instead of matched once across the long baseline, where repeated texture along the epipolar line
passes every check of the geometry.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from vehicle.vision.ncc import patches

LK_WINDOW = (15, 15)
LK_LEVELS = 2


@dataclass
class CornerTracks:
    """The live tracks (ids (n,), pixels (n, 2) as (col, row)), each track's first patch, and the pixels
    of the tracks in each frame kept (``history``: frame -> (ids, pixels))."""

    max_tracks: int = 300
    min_spacing_px: float = 8.0
    fb_px: float = 0.5
    min_ncc: float = 0.8
    half: int = 5  # the patch compared with the track's first: (2 half + 1)^2 pixels
    keep_frames: int = 12
    ids: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    xy: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), np.float32))
    first_patch: np.ndarray | None = None  # (n, (2 half + 1)^2), zero-mean and unit-norm (ncc.patches)
    history: dict[int, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)
    _previous: np.ndarray | None = None
    _next_id: int = 0

    def __post_init__(self) -> None:
        if self.first_patch is None:
            self.first_patch = np.zeros((0, (2 * self.half + 1) ** 2), np.float32)

    def step(self, frame: int, image: np.ndarray, corners: np.ndarray) -> None:
        """Follow the live tracks into ``image`` (H, W) uint8, frame number ``frame``, and start tracks
        at ``corners`` (k, 2) (strongest first) away from them."""
        if self._previous is not None and len(self.xy):
            self._follow(image)
        self._start(image, corners)
        self._previous = image
        self.history[frame] = (self.ids.copy(), self.xy.astype(float))
        self.history.pop(frame - self.keep_frames, None)

    def pairs(self, j: int, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The tracks alive in frames j and k: their pixels in j (m, 2), in k (m, 2), and their ids (m,)."""
        ids_j, xy_j = self.history[j]
        ids_k, xy_k = self.history[k]
        common, in_j, in_k = np.intersect1d(ids_j, ids_k, return_indices=True)
        return xy_j[in_j], xy_k[in_k], common

    def _follow(self, image: np.ndarray) -> None:
        ahead, ok = _lucas_kanade(self._previous, image, self.xy)
        back, ok_back = _lucas_kanade(image, self._previous, ahead)
        keep = ok & ok_back & (np.linalg.norm(back - self.xy, axis=1) < self.fb_px)
        keep &= _inside(ahead, image.shape, self.half)
        now = np.zeros_like(self.first_patch)
        now[keep] = patches(image, ahead[keep], self.half)[0]
        keep &= np.einsum("ij,ij->i", now, self.first_patch) >= self.min_ncc
        self.ids, self.xy, self.first_patch = self.ids[keep], ahead[keep], self.first_patch[keep]

    def _start(self, image: np.ndarray, corners: np.ndarray) -> None:
        room = self.max_tracks - len(self.ids)
        if room <= 0 or not len(corners):
            return
        fresh = corners[_inside(corners, image.shape, self.half)]
        if len(self.xy):
            nearest = np.linalg.norm(fresh[:, None, :] - self.xy[None, :, :], axis=-1).min(axis=1)
            fresh = fresh[nearest >= self.min_spacing_px]
        fresh = fresh[:room]
        self.ids = np.concatenate([self.ids, self._next_id + np.arange(len(fresh))])
        self._next_id += len(fresh)
        self.xy = np.vstack([self.xy, fresh.astype(np.float32)])
        self.first_patch = np.vstack([self.first_patch, patches(image, fresh, self.half)[0]])


def _lucas_kanade(before: np.ndarray, after: np.ndarray, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pixels ``xy`` (n, 2) of image ``before`` followed into ``after``: where (n, 2), and found (n,)."""
    start = xy.reshape(-1, 1, 2).astype(np.float32)
    moved, found, _ = cv2.calcOpticalFlowPyrLK(before, after, start, None, winSize=LK_WINDOW, maxLevel=LK_LEVELS)
    return moved.reshape(-1, 2), found.ravel() == 1


def _inside(xy: np.ndarray, shape: tuple[int, ...], half: int) -> np.ndarray:
    """Which pixels (n, 2) have a whole patch of half-width ``half`` in an image of ``shape`` (a pixel
    away from the border by a margin of one: ncc.patches then finds a patch for every one)."""
    return (xy[:, 0] >= half) & (xy[:, 1] >= half) & (xy[:, 0] < shape[1] - half - 1) & (xy[:, 1] < shape[0] - half - 1)
