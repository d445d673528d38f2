"""Where the full-resolution colour search looks: windows around what the search found on a
half-size copy of the frame, and the blurred HSV pixels of those windows only, exactly what
blurring and converting the whole frame would give there (signs/proposals.py).

A sign is a small part of a road frame: blurring, converting and thresholding every pixel at
full resolution is most of the proposals' cost, and the half-size search already says where
the signs are.

All images are uint8 BGR (H, W, 3); boxes (x0, y0, x1, y1) full-resolution pixels, exclusive.
"""
from __future__ import annotations

import cv2
import numpy as np

Box = tuple[int, int, int, int]
PAD_FRAC = 0.35  # a window reaches this share of a coarse box's size beyond it on every side ...
PAD_MIN = 10  # ... and at least this many pixels: a coarse box is off by a pixel or two, a ring's closing by 7


def windows(coarse_boxes: list[tuple[int, int, int, int]], scale: tuple[float, float], frame_wh: tuple[int, int],
            min_pad: int) -> list[Box]:
    """Full-resolution windows (x0, y0, x1, y1) around a half-size frame's (x, y, w, h) boxes,
    clipped to the frame; overlapping windows are merged so that a blob is searched once."""
    W, H = frame_wh
    sx, sy = scale
    out = []
    for x, y, w, h in coarse_boxes:
        pad = max(PAD_MIN, min_pad // 2, int(PAD_FRAC * max(w * sx, h * sy)))
        out.append([max(0, int(x * sx) - pad), max(0, int(y * sy) - pad), min(W, int(np.ceil((x + w) * sx)) + pad),
                    min(H, int(np.ceil((y + h) * sy)) + pad)])
    return [tuple(b) for b in _merge(out, 0)]


def _merge(boxes: list[list[int]], gap: int) -> list[list[int]]:
    """Union boxes that overlap or lie within `gap` px of each other, until none do."""
    merged = True
    while merged:
        merged = False
        out: list[list[int]] = []
        for b in boxes:
            for o in out:
                if b[0] < o[2] + gap and o[0] < b[2] + gap and b[1] < o[3] + gap and o[1] < b[3] + gap:
                    o[:] = [min(o[0], b[0]), min(o[1], b[1]), max(o[2], b[2]), max(o[3], b[3])]
                    merged = True
                    break
            else:
                out.append(list(b))
        boxes = out
    return boxes


def blurred_hsv(image: np.ndarray, box: Box, blur_px: int) -> np.ndarray:
    """uint8 (y1 - y0, x1 - x0, 3): the HSV of the blurred frame inside box, pixel for pixel
    what blurring the whole frame gives: the blur sees the real pixels beyond the box (and
    OpenCV's reflected border only at the frame's own edge)."""
    x0, y0, x1, y1 = box
    H, W = image.shape[:2]
    r = (blur_px | 1) // 2 if blur_px > 1 else 0
    ex0, ey0, ex1, ey1 = max(0, x0 - r), max(0, y0 - r), min(W, x1 + r), min(H, y1 + r)
    part = image[ey0:ey1, ex0:ex1]
    if r:
        part = cv2.GaussianBlur(part, (blur_px | 1, blur_px | 1), 0)
    return cv2.cvtColor(np.ascontiguousarray(part[y0 - ey0:y1 - ey0, x0 - ex0:x1 - ex0]), cv2.COLOR_BGR2HSV)
