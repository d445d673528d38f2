"""The junction detector's colour rule for road, in integer Lab boxes (cv2.inRange), is the rule
as written: within lab_tol of the patch ahead's median (its integer part), or darker than it
down to shadow_floor of it with the same tint, or paint (25 lighter, colourless); seen ground
only; specks opened away."""
import cv2
import numpy as np

from signlane.camera import via_camera
from signlane.junction import JunctionDetector


def _rule(det: JunctionDetector, image: np.ndarray) -> np.ndarray:
    p = det.p
    lab = cv2.cvtColor(det.bev.warp(image), cv2.COLOR_BGR2LAB).astype(np.int16)
    rows = slice(int((p.y_range_m[1] - p.y_range_m[0] - 3.0) * p.px_per_m), int((p.y_range_m[1] - p.y_range_m[0]) * p.px_per_m))
    ref = np.median(lab[rows, det._col(-0.9):det._col(0.9)].reshape(-1, 3), axis=0)
    d = np.abs(lab - ref.astype(np.int16))
    light = (d[..., 0] < p.lab_tol[0]) | ((lab[..., 0] < ref[0]) & (lab[..., 0] > p.shadow_floor * ref[0]))
    road = light & (d[..., 1] < p.lab_tol[1]) & (d[..., 2] < p.lab_tol[2])
    paint = (lab[..., 0] > ref[0] + 25) & (np.abs(lab[..., 1] - 128) < 20)
    mask = ((road | paint) & det.visible).astype(np.uint8) * 255
    return cv2.morphologyEx(mask, cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))


def test_the_road_mask_is_the_rule_on_every_kind_of_frame():
    det = JunctionDetector(via_camera(320, 240))
    rng = np.random.default_rng(5)
    frames = []
    for _ in range(60):
        img = np.empty((240, 320, 3), np.uint8)
        img[:120] = rng.integers(0, 256, 3)  # sky
        img[120:] = rng.integers(0, 256, 3)  # ground of one colour, then texture, shadows and paint on it
        img[120:] = np.clip(img[120:].astype(int) + rng.integers(-40, 40, (120, 320, 1)), 0, 255)
        cv2.rectangle(img, (int(rng.integers(0, 300)), 150), (int(rng.integers(0, 320)), 239),
                      tuple(int(v) for v in rng.integers(0, 256, 3)), -1)
        cv2.line(img, (160, 239), (int(rng.integers(100, 220)), 130), (250, 250, 250), 3)
        frames.append(img)
    frames += [np.full((240, 320, 3), v, np.uint8) for v in (0, 1, 128, 231, 254, 255)]
    for img in frames:
        want, got = _rule(det, img), det.road_mask(img)
        assert np.array_equal(want, got), int((want != got).sum())
    assert any(det.road_mask(f).any() for f in frames) and not all(det.road_mask(f).all() for f in frames)
