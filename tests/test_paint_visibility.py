"""Which labelled paint a frame shows: contrast in CIELAB against the ground beside it, and the
paint under 4 levels that the lane generator leaves unlabelled."""
from __future__ import annotations

import cv2
import numpy as np

from signlane.paint_visibility import paint_contrast, unseen_paint


def _road_with_strips(levels: list[tuple[int, int, int]], road=(90, 90, 90), noise: float = 0.0):
    """A grey road (BGR) with one 4 px vertical strip of each colour, 30 px apart; the strips' mask."""
    img = np.full((60, 40 + 30 * len(levels), 3), road, np.float32)
    paint = np.zeros(img.shape[:2], bool)
    for k, colour in enumerate(levels):
        x = 20 + 30 * k
        img[:, x:x + 4] = colour
        paint[:, x:x + 4] = True
    if noise:
        img += np.random.default_rng(0).normal(0, noise, img.shape)
    return np.clip(img, 0, 255).astype(np.uint8), paint


def test_contrast_is_the_lab_distance_to_the_ground_beside_the_paint():
    img, paint = _road_with_strips([(92, 92, 92), (120, 120, 120), (220, 220, 220)])
    c = paint_contrast(img, paint, ~paint)
    assert np.isnan(c[~paint]).all()
    col = [float(np.median(c[:, 20 + 30 * k:24 + 30 * k])) for k in range(3)]
    assert col[0] < 3 < 15 < col[1] < 40 < col[2]  # 2, 30 and 130 grey levels of difference, in L
    assert unseen_paint(img, paint, ~paint)[:, 20:24].all()
    assert not unseen_paint(img, paint, ~paint)[:, 50:54].any()


def test_colour_counts_not_only_lightness():
    """Yellow paint as light as the grey road is plain to see: its a/b differ."""
    road = (110, 110, 110)
    grey_l = cv2.cvtColor(np.uint8([[road]]), cv2.COLOR_BGR2LAB)[0, 0, 0]
    yellow = next((0, g, g) for g in range(60, 256)
                  if abs(int(cv2.cvtColor(np.uint8([[(0, g, g)]]), cv2.COLOR_BGR2LAB)[0, 0, 0]) - int(grey_l)) <= 1)
    img, paint = _road_with_strips([yellow], road=road)
    assert not unseen_paint(img, paint, ~paint).any()


def test_sensor_noise_does_not_make_seen_paint_unseen():
    """Paint 12 levels lighter under noise of sigma 6 stays labelled (the 3x3 paint mean), paint
    1 level lighter under the same noise stays unseen in most of its pixels."""
    img, paint = _road_with_strips([(102, 102, 102), (91, 91, 91)], noise=6.0)
    unseen = unseen_paint(img, paint, ~paint)
    assert unseen[:, 20:24].mean() < 0.02
    assert unseen[:, 50:54].mean() > 0.6


def test_paint_with_no_ground_near_is_kept():
    img = np.full((30, 30, 3), 90, np.uint8)
    paint = np.ones((30, 30), bool)  # all paint: nothing to compare it with
    assert np.isnan(paint_contrast(img, paint, ~paint)).all()
    assert not unseen_paint(img, paint, ~paint).any()
