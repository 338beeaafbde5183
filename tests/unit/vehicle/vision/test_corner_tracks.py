"""Corners followed from frame to frame (vehicle.vision.corner_tracks): on a texture moved by known
shifts the tracks follow it to a hundredth of a pixel and keep their ids; a frame that shows something
else ends nine in ten of them (forward-backward check; a few land on look-alike texture, which the
geometry is for), and so does a patch that no longer looks like its first; new
corners keep their distance from the live tracks."""

from __future__ import annotations

import cv2
import numpy as np

from vehicle.vision import susan
from vehicle.vision.corner_tracks import CornerTracks

SIZE = (240, 320)


def _texture(seed: int) -> np.ndarray:
    """A smooth grey texture (H, W) uint8 with structure at two scales."""
    rng = np.random.default_rng(seed)
    coarse = cv2.resize(rng.uniform(0, 255, (30, 40)), SIZE[::-1], interpolation=cv2.INTER_CUBIC)
    fine = cv2.GaussianBlur(rng.uniform(0, 255, SIZE), (0, 0), 1.5)
    return np.clip(0.7 * coarse + 0.3 * fine, 0, 255).astype(np.uint8)


def _shifted(image: np.ndarray, shift: np.ndarray) -> np.ndarray:
    """``image`` moved by ``shift`` (2,) px (col, row), bilinear."""
    M = np.array([[1.0, 0.0, shift[0]], [0.0, 1.0, shift[1]]])
    return cv2.warpAffine(image, M, SIZE[::-1], flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)


def test_tracks_follow_a_moving_texture_to_a_fraction_of_a_pixel_and_keep_their_ids():
    base = _texture(0)
    step = np.array([1.3, -0.7])
    tracks = CornerTracks()
    for k in range(11):
        image = _shifted(base, k * step)
        tracks.step(k, image, susan.corners(image)[0])
    p0, p10, ids = tracks.pairs(0, 10)
    first_ids = tracks.history[0][0]
    assert len(ids) >= 0.8 * len(first_ids) and len(ids) > 50  # most followed all ten frames
    error = np.linalg.norm(p10 - (p0 + 10 * step), axis=1)
    assert np.median(error) < 0.01 and error.max() < 0.2


def test_a_frame_that_shows_something_else_ends_the_tracks():
    tracks = CornerTracks(max_tracks=100)
    first = _texture(1)
    tracks.step(0, first, susan.corners(first)[0])
    other = _texture(2)
    tracks.step(1, other, np.zeros((0, 2)))  # no new corners: only what was followed
    assert len(tracks.history[0][0]) > 50
    assert len(tracks.ids) < 0.1 * len(tracks.history[0][0])  # a few may land on a look-alike, no more


def test_a_track_whose_patch_no_longer_looks_like_its_first_is_let_go():
    base = _texture(3)
    tracks = CornerTracks()
    tracks.step(0, base, susan.corners(base)[0])
    ids, xy = tracks.ids.copy(), tracks.xy.copy()
    changed = base.copy()
    col, row = np.rint(xy[0]).astype(int)
    patch = np.rot90(base[row - 8 : row + 9, col - 8 : col + 9])  # the same texture, turned: LK may follow it
    changed[row - 8 : row + 9, col - 8 : col + 9] = patch
    tracks.step(1, changed, np.zeros((0, 2)))
    assert ids[0] not in tracks.ids
    assert np.isin(ids[1:], tracks.ids).mean() > 0.9  # the rest go on


def test_new_corners_keep_their_distance_from_live_tracks_up_to_the_cap():
    image = _texture(4)
    corners = susan.corners(image)[0]
    tracks = CornerTracks(max_tracks=40, min_spacing_px=8.0)
    tracks.step(0, image, corners)
    assert len(tracks.ids) == 40
    tracks = CornerTracks(max_tracks=10_000, min_spacing_px=8.0)
    tracks.step(0, image, corners)
    tracks.step(1, image, corners)  # the same corners again: each lies on a live track
    d = np.linalg.norm(tracks.xy[:, None] - tracks.xy[None], axis=-1) + 1e9 * np.eye(len(tracks.xy))
    started_again = len(tracks.ids) - len(tracks.history[0][0])
    assert started_again <= 0.05 * len(tracks.history[0][0])
    assert np.sum(d.min(axis=1) < 1.0) <= 2 * started_again  # no corner doubled on a live track
