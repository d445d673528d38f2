"""A segmentation model's lane-marking mask, drawn as sharp as the frame's own pixels.

The model answers at its output size (160x120 for the shipped one): brought up to a 960x540
photo, each of its cells spans 6 pixels, and a line it found becomes a band several pixels wider
than the paint. Scored within 2 px of hand-drawn paint, the band's margins count as false paint.
Inside the band the frame itself says where the paint is: paint is lighter than the road around
it. So where one output cell spans at least `min_cell_px` frame pixels, a band pixel is kept
where its lightness above the local ground (a white top-hat: the lightness less its opening over
a window reaching `reach_cells` cells either side, wider than any line's band) reaches
`keep_share` of the highest such value near it; where that highest value is under
`min_contrast` levels, the image shows no line there (night, fog, glare) and the band is kept as
the model drew it.

The numbers were chosen on heavy mixed dev sets (`eval masks`, the shipped model; seeds 9100 at
960 wide, 9101 at 640x480, 7243 at 320x240); on fresh ones (500 frames each) marking F1 goes from
0.902 to 0.909 at 640x480 (seed 9201) and from 0.849 to 0.880 at 960 wide (seed 9200), precision
up 2-7 points, recall down about one. At 320x240 (cells of 2 px, within the tolerance) it cost
0.001 on the dev set, so it stays off there.
It costs about 3 ms at 640x480 and 8 ms at 960x540: `infer --save-masks` and `eval masks` pay
it, the car's lane method does not (its lanes come from the model's own map).
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np


@dataclass(frozen=True)
class SharpParams:
    min_cell_px: float = 3.0  # sharpen only where one output cell spans this many frame pixels
    reach_cells: float = 5.0  # the top-hat's window reaches this many output cells either side of a pixel
    keep_share: float = 0.3  # a band pixel is paint at this share of the nearby peak lightness step
    min_contrast: float = 6.0  # a nearby peak under this (CIELAB L levels, 0-255): no line seen


def sharpen_marking(band: np.ndarray, image_bgr: np.ndarray, map_size: tuple[int, int],
                    p: SharpParams = SharpParams()) -> np.ndarray:
    """uint8 (H, W) marking band at the frame's size (nonzero: the model's map brought up to
    it), the uint8 (H, W, 3) BGR frame, and the (w, h) of the model's map -> uint8 (H, W) 0/255,
    the band's pixels that are the paint."""
    if band.shape != image_bgr.shape[:2]:
        raise ValueError(f"marking band {band.shape} is not the frame's size {image_bgr.shape[:2]}")
    cell_px = max(band.shape[1] / map_size[0], band.shape[0] / map_size[1])  # frame pixels per output cell
    if cell_px < p.min_cell_px or not band.any():
        return band
    k = 2 * max(1, int(round(p.reach_cells * cell_px))) + 1
    window = cv2.getStructuringElement(cv2.MORPH_RECT, (k, k))
    light = cv2.cvtColor(image_bgr, cv2.COLOR_BGR2LAB)[:, :, 0]
    step = cv2.morphologyEx(light, cv2.MORPH_TOPHAT, window)  # lightness above the local ground
    on = band > 0
    peak = cv2.dilate(np.where(on, step, np.uint8(0)), window)  # the band's highest step near each pixel
    paint = (step.astype(np.float32) >= p.keep_share * peak) | (peak < p.min_contrast)
    return np.where(paint & on, np.uint8(255), np.uint8(0))
