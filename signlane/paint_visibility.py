"""How far lane paint stands out of the ground beside it in a frame, and which paint a frame does
not show at all.

The renderer knows where paint lies; the photometric effects (night, fog, glare, an exposure
that whites the road out) and a random look (a pale road under white paint) can leave some of it
the road's own colour. A label that calls such a pixel paint asks a model to see what is not in
the image: it teaches guessing and scores every method against paint nobody could find. So the
generators label it as unknown (255), like a kerb, and `signlane eval masks` splits its recall by
the same measure.

The measure: the CIELAB distance (8-bit OpenCV scale: L 0-255, a and b offset by 128) between a
paint pixel's colour, averaged over the paint within 3x3 of it (sensor noise on one pixel is not
paint), and the mean colour of the labelled ground that is not paint within `box` px of it.
Under about 4 levels a line cannot be told from the road.
"""
from __future__ import annotations

import cv2
import numpy as np

UNSEEN_BELOW = 4.0  # contrast levels under which paint is not in the image
BOX = 15  # px: the ground around a paint pixel that it is seen against


def _local_mean(lab: np.ndarray, where: np.ndarray, size: int) -> tuple[np.ndarray, np.ndarray]:
    """Mean Lab colour of the `where` pixels in a size x size window around each pixel, and the
    count of them."""
    weight = where.astype(np.float32)
    count = cv2.boxFilter(weight, -1, (size, size), normalize=False, borderType=cv2.BORDER_CONSTANT)
    total = cv2.boxFilter(lab * weight[:, :, None], -1, (size, size), normalize=False,
                          borderType=cv2.BORDER_CONSTANT)
    return total / np.maximum(count, 1.0)[:, :, None], count


def paint_contrast(image_bgr: np.ndarray, paint: np.ndarray, ground: np.ndarray, box: int = BOX) -> np.ndarray:
    """float32 (H, W): on each `paint` pixel (bool (H, W)) its contrast against the `ground`
    (bool (H, W), labelled non-paint) within `box` px; NaN on paint with no ground that near (its
    contrast cannot be measured) and off the paint."""
    out = np.full(paint.shape, np.nan, np.float32)
    if not paint.any():
        return out
    lab = cv2.cvtColor(image_bgr, cv2.COLOR_BGR2LAB).astype(np.float32)
    paint_colour, _ = _local_mean(lab, paint, 3)
    ground_colour, ground_n = _local_mean(lab, ground, box)
    distance = np.linalg.norm(paint_colour - ground_colour, axis=2)
    measured = paint & (ground_n > 0)
    out[measured] = distance[measured]
    return out


def unseen_paint(image_bgr: np.ndarray, paint: np.ndarray, ground: np.ndarray,
                 below: float = UNSEEN_BELOW) -> np.ndarray:
    """bool (H, W): the paint pixels whose contrast is under `below` levels (not in the image)."""
    contrast = paint_contrast(image_bgr, paint, ground)
    with np.errstate(invalid="ignore"):
        return contrast < below  # NaN (not paint, or nothing to compare with) is False
