"""A road model's road mask checked against this world's own colours.

A road model reads road by shape as much as by colour: it has learned that a random look's road
may wear another look's grass colour. Where a painted road has no edge line and its verge is
only a little greener or browner than its asphalt, it can take metres of verge for road (random
looks, traced: the grass before a crossing read as road 4 m deep, taken for the side road, and
the car turned onto the grass). The colours of one world barely change from frame to frame, so
they are learned as the car drives: the asphalt's chromaticity from the patch just ahead that
the model calls road, the verge's from what it calls off-road, each a running average over
frames. Where the two differ enough to tell apart, a pixel the model calls road whose colour lies
on the verge's side of the two is not road. Chromaticity (each channel's share of the pixel's
sum) is what a shadow or a darker patch of asphalt leaves alone, so shade is not taken for verge.
Where road and verge share a colour the check stands aside and the model decides alone.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np


@dataclass(frozen=True)
class RoadColourParams:
    memory: float = 0.9  # weight of the past in each colour's running average (the look of the world changes slowly)
    min_pixels: int = 15  # a colour is updated from a frame only with this many pixels of it (at half size)
    # road and verge chromaticities closer than this cannot be told apart by colour (the traced
    # grey road and grey-green verge: 0.042; the texture's spread within one surface: about 0.01)
    min_separation: float = 0.025
    # a road pixel is verge when its colour lies this far along the way from the road's colour
    # to the verge's (0.5: nearer the verge's; more: a margin for the texture's noise)
    verge_side: float = 0.6
    min_sum: int = 45  # B + G + R below this: too dark for its chromaticity to mean anything


@dataclass(frozen=True)
class RoadColours:
    """The running chromaticities, (b, g) shares, of this world's road and of its verge (None: not
    yet seen). A new drive, perhaps in another world, starts from RoadColours()."""

    road: tuple[float, float] | None = None
    verge: tuple[float, float] | None = None


def _running(old: tuple[float, float] | None, share_b: np.ndarray, share_g: np.ndarray, where: np.ndarray,
             p: RoadColourParams) -> tuple[float, float] | None:
    if np.count_nonzero(where) < p.min_pixels:
        return old
    new = np.array([np.median(share_b[where]), np.median(share_g[where])])
    mixed = new if old is None else p.memory * np.asarray(old) + (1.0 - p.memory) * new
    return float(mixed[0]), float(mixed[1])


def check_road_colour(road: np.ndarray, image_bgr: np.ndarray, ahead: np.ndarray, seen: np.ndarray,
                      colours: RoadColours, p: RoadColourParams, keep: np.ndarray | None = None
                      ) -> tuple[np.ndarray, RoadColours]:
    """(bool road mask (h, w) of a view without the pixels whose colour is the verge's, the
    colours updated with this frame's). `image_bgr`: uint8 (h, w, 3), the same view; `ahead`:
    bool (h, w), the ground just ahead of the car (the road's colour); `seen`: bool (h, w), the
    ground the view shows; `keep`: bool (h, w) pixels kept whatever their colour (paint: white
    and yellow lines lie on any road). Colours are read and judged at half the view's size (each
    pixel the mean of four, which also evens out the texture), and the verge found there is
    taken back to the view's pixels."""
    h, w = road.shape
    half = (max(w // 2, 1), max(h // 2, 1))
    b, g, r = cv2.split(cv2.resize(image_bgr, half, interpolation=cv2.INTER_AREA).astype(np.float32))
    total = b + g + r
    lit = total >= p.min_sum
    some = np.maximum(total, 1.0)
    share_b, share_g = b / some, g / some  # (r's share is what is left)
    road_h = cv2.resize(road.view(np.uint8), half, interpolation=cv2.INTER_NEAREST) > 0
    seen_h = cv2.resize(seen.view(np.uint8), half, interpolation=cv2.INTER_NEAREST) > 0
    ahead_h = cv2.resize(ahead.view(np.uint8), half, interpolation=cv2.INTER_NEAREST) > 0
    lit &= seen_h
    colours = RoadColours(_running(colours.road, share_b, share_g, road_h & ahead_h & lit, p),
                          _running(colours.verge, share_b, share_g, ~road_h & lit, p))
    if colours.road is None or colours.verge is None:
        return road, colours
    asphalt = np.asarray(colours.road)
    axis = np.asarray(colours.verge) - asphalt
    gap = float(np.hypot(*axis))
    if gap < p.min_separation:
        return road, colours
    # a pixel is the verge's when its shares (b, g) = (B, G) / S, S = B + G + R, lie past
    # verge_side of the way from the road's colour to the verge's: (b, g) . axis > c, or, times
    # S (> 0), B (ax - c) + G (ay - c) - R c > 0, a weighted sum of its channels
    c = p.verge_side * gap * gap + float(asphalt @ axis)
    verge_h = ((b * np.float32(axis[0] - c) + g * np.float32(axis[1] - c) - r * np.float32(c)) > 0) & lit
    verge = cv2.resize(verge_h.view(np.uint8), (w, h), interpolation=cv2.INTER_NEAREST) > 0
    if keep is not None:
        verge &= ~keep
    return road & ~verge, colours
