"""SUSAN corners (Smith and Brady, "SUSAN - a new approach to low level image processing", IJCV 1997),
the AR-EKF-SLAM paper's corner detector, vectorised over the whole frame. Pure.

For each pixel (the nucleus r0) the 37-pixel circular mask (radius 3.4 px) counts how much of its
area has the nucleus's brightness, c(r, r0) = exp(-((I(r) - I(r0)) / t)^6) summed into the USAN area
n(r0) (Smith and Brady's eqs. 3-4). A corner is where that area is small: the response is
g - n(r0) where n(r0) < g, with the geometric threshold g = n_max / 2 (eq. 5). False positives
(the paper's two tests, with the thresholds of Smith's reference implementation): the USAN's centre
of gravity must lie more than 1 / sqrt(2) px from the nucleus (a thin line's USAN is centred on it),
and the three pixels on the way from the nucleus towards that centre (in steps of one pixel along
its larger component) must belong to the USAN (contiguity: their similarities summing to more than
2.9). Non-maximum suppression in a 7 x 7 window keeps one response per corner. No maintained
library ships SUSAN (OpenCV does not), hence this module.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import cv2
import numpy as np

RADIUS = 3
WIDTHS = (3, 5, 7, 7, 7, 5, 3)  # the 37-pixel mask, row by row


def mask_offsets() -> np.ndarray:
    """The mask's (d row, d col) offsets (37, 2)."""
    return np.array(
        [
            (dr, dc)
            for dr, width in zip(range(-RADIUS, RADIUS + 1), WIDTHS)
            for dc in range(-(width // 2), width // 2 + 1)
        ]
    )


@cache
def _similarity(t: float) -> np.ndarray:
    """c for every brightness difference -255..255 (eq. 4), as a lookup table (511,)."""
    d = np.arange(-255, 256, dtype=float)
    return np.exp(-((d / t) ** 6))


@dataclass(frozen=True)
class SusanSpec:
    t: float = 20.0  # brightness threshold (grey levels): the noise a nucleus's area tolerates
    geometric: float = 0.5  # g as a share of n_max (1/2: corners; 3/4 would be edges)
    min_centroid_px: float = 1.0 / np.sqrt(2.0)
    min_contiguity: float = 2.9  # of 3: the similarity of the three pixels towards the centre of gravity
    suppression_px: int = 7
    max_corners: int = 1000


def usan(image: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
    """The USAN area n (H, W) and the offset of its centre of gravity from the nucleus (H, W, 2) as
    (d row, d col) for a grey uint8 image (H, W); the border is the edge pixels repeated."""
    lut = _similarity(t)
    h, w = image.shape
    padded = np.pad(image.astype(np.int16), RADIUS, mode="edge")
    centre = image.astype(np.int16)
    area = np.zeros((h, w))
    moment = np.zeros((h, w, 2))
    for dr, dc in mask_offsets():
        c = lut[padded[RADIUS + dr : RADIUS + dr + h, RADIUS + dc : RADIUS + dc + w] - centre + 255]
        area += c
        moment[..., 0] += dr * c
        moment[..., 1] += dc * c
    return area, moment / np.maximum(area, 1e-12)[..., None]


def corners(image: np.ndarray, spec: SusanSpec = SusanSpec()) -> tuple[np.ndarray, np.ndarray]:
    """SUSAN corners of a grey uint8 image: pixel positions (k, 2) as (col, row) and responses (k,),
    strongest first, at most ``spec.max_corners``."""
    area, centroid = usan(image, spec.t)
    g = spec.geometric * len(mask_offsets())
    response = np.where(area < g, g - area, 0.0)
    distance = np.linalg.norm(centroid, axis=-1)
    response[distance <= spec.min_centroid_px] = 0.0
    response[_contiguity(image, centroid, spec.t) <= spec.min_contiguity] = 0.0
    response = response.astype(np.float32)  # the dilation's type: a peak must equal its own maximum
    peak = cv2.dilate(response, np.ones((spec.suppression_px, spec.suppression_px), np.uint8))
    rows, cols = np.nonzero((response > 0) & (response >= peak))
    strength = response[rows, cols]
    order = np.argsort(-strength, kind="stable")[: spec.max_corners]
    return np.column_stack([cols[order], rows[order]]).astype(float), strength[order]


def _contiguity(image: np.ndarray, centroid: np.ndarray, t: float) -> np.ndarray:
    """The summed similarity to the nucleus (H, W) of the three pixels one, two and three steps from it
    towards the USAN's centre of gravity, a step being one pixel along the centre's larger component."""
    lut = _similarity(t)
    h, w = image.shape
    pad = RADIUS
    padded = np.pad(image.astype(np.int16), pad, mode="edge")
    larger = np.maximum(np.abs(centroid).max(axis=-1), 1e-12)
    step = centroid / larger[..., None]  # (d row, d col) with the larger component +-1
    rows, cols = np.mgrid[0:h, 0:w]
    total = np.zeros((h, w))
    for k in (1, 2, 3):
        r = np.clip(np.rint(rows + k * step[..., 0]).astype(int), -pad, h - 1 + pad) + pad
        c = np.clip(np.rint(cols + k * step[..., 1]).astype(int), -pad, w - 1 + pad) + pad
        total += lut[padded[r, c] - image.astype(np.int16) + 255]
    return total
