"""The pixels the colour search of the sign proposals looks at (signs/proposals.py): per window
of the frame, one saturation plane per colour, 0 where the pixel's hue, value or chroma is not
the colour's, so that each saturation level of the search is one threshold; and the frame's
percentiles that adapt the thresholds.

All images are uint8; HSV is OpenCV's (hue 0..179); boxes (x0, y0, x1, y1) frame pixels, exclusive.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

Box = tuple[int, int, int, int]
HueRange = tuple[int, int]


@dataclass(frozen=True)
class Window:
    """The pixels of one region (x0, y0, x1, y1) of the frame that the search looks at: their
    HSV (ring interiors are judged there) and, per colour, their saturation where the pixel has
    the colour's hue, V and chroma, 0 elsewhere, so that a saturation level is one threshold."""

    box: Box
    hsv: np.ndarray
    sat: dict[str, np.ndarray]

    def crop(self, plane: np.ndarray, box: Box) -> np.ndarray:
        """`plane`'s pixels inside box (x0, y0, x1, y1), frame pixels, which lies inside the window."""
        x0, y0 = self.box[:2]
        return plane[box[1] - y0:box[3] - y0, box[0] - x0:box[2] - x0]


def window(hsv: np.ndarray, box: Box, specs, c_min: float) -> Window:
    """The window of `hsv` (uint8 (h, w, 3), the HSV of region `box`) for the colours of specs
    ((colour, hue ranges, first S level, V minimum), ...), pixels below the chroma floor c_min
    (S * V / 255) left out."""
    hue, sat, val = cv2.split(hsv)
    ok = None
    if c_min > 0:
        chroma = cv2.multiply(sat, val, scale=1 / 255.0)
        ok = cv2.threshold(chroma, c_min - 1e-3, 255, cv2.THRESH_BINARY)[1]
    out = {}
    for color, hues, _, v_min in specs:
        m = cv2.bitwise_and(hue_ok(hue, hues), cv2.threshold(val, v_min - 1, 255, cv2.THRESH_BINARY)[1])
        if ok is not None:
            cv2.bitwise_and(m, ok, dst=m)
        out[color] = cv2.bitwise_and(sat, m)
    return Window(box, hsv, out)


def hue_ok(hue: np.ndarray, hues: tuple[HueRange, ...]) -> np.ndarray:
    """uint8 0/255: hue inside any of the (lo, hi) ranges, inclusive (cv2.inRange's rule). A range
    open at an end of OpenCV's 8-bit hue (0..179) is one threshold, which costs a third of
    inRange (red's two ranges are)."""
    mask = None
    for lo, hi in hues:
        if lo <= 0:
            m = cv2.threshold(hue, hi, 255, cv2.THRESH_BINARY_INV)[1]
        elif hi >= 179:
            m = cv2.threshold(hue, lo - 1, 255, cv2.THRESH_BINARY)[1]
        else:
            m = cv2.inRange(hue, lo, hi)
        mask = m if mask is None else cv2.bitwise_or(mask, m, dst=mask)
    return mask


def level_mask(sat: np.ndarray, s_min: int, kernel: np.ndarray | None) -> np.ndarray:
    """Pixels of a window's colour plane (crop) at saturation >= s_min; the plane is 0 where the
    hue is not the colour's, so a level counts from 1 (a grey pixel has no hue)."""
    _, mask = cv2.threshold(sat, max(s_min, 1) - 1, 255, cv2.THRESH_BINARY)
    return mask if kernel is None else cv2.morphologyEx(mask, cv2.MORPH_CLOSE, kernel)


def percentile_u8(values: np.ndarray, q: float) -> float:
    """np.percentile(values, q) (linear method, the same float) of a non-empty uint8 array, from
    a 256-bin histogram: np.percentile sorts a copy, which cost more than the rest of the frame
    statistics together."""
    cum = np.cumsum(np.bincount(values.reshape(-1), minlength=256))
    n = int(cum[-1])
    pos = (n - 1) * (q / 100)
    lo = int(np.floor(pos))
    t = pos - lo
    a = int(np.searchsorted(cum, lo, side="right"))  # the lo-th smallest value ...
    b = int(np.searchsorted(cum, min(lo + 1, n - 1), side="right"))  # ... and the next
    d = b - a
    return float(b - d * (1 - t)) if t >= 0.5 else float(a + d * t)  # numpy's own lerp, both halves
