"""The lane-method contract, checked the same way for the methods that share the marking-point
back-end (canny-scan, color-hough): offsets within a tenth of the lane, signs of offset and
heading, the debug mask on the paint, confidence when one side is gone."""
import math

import cv2
import numpy as np
import pytest

from lane_helpers import CAM, STRAIGHTS, run_method as run
from signlane.world.sampling import FrameSampler, SamplerConfig

METHODS = pytest.mark.parametrize("method", ["canny-scan", "color-hough"])


@METHODS
def test_clean_frames_offset_within_a_tenth_of_the_lane(method):
    smp = FrameSampler(7, SamplerConfig(effects="clean", randomise=False))
    errs = []
    for i in range(0, 60, 5):
        s = smp.sample(i)
        est = run(method, s.image, s.truth.nominal_camera)
        assert est.found, f"frame {i}"
        errs.append(abs(est.offset - s.truth.offset))
    # at most one frame of twelve off (canny-scan: asphalt texture taken for the centre line)
    errs = np.array(errs)
    assert (errs >= 0.1).sum() <= 1 and np.median(errs) < 0.04, errs.round(3)


@METHODS
def test_normal_frames_mostly_found_and_close(method):
    smp = FrameSampler(7, SamplerConfig())
    errs = []
    for i in range(0, 60, 5):
        s = smp.sample(i)
        est = run(method, s.image, s.truth.nominal_camera)
        if est.found:
            errs.append(abs(est.offset - s.truth.offset))
    assert len(errs) >= 9 and np.median(errs) < 0.06


@METHODS
@pytest.mark.parametrize("s", STRAIGHTS)
def test_lateral_displacement_gives_the_offset_sign_and_size(method, lane_loop, s):
    route, renderer = lane_loop
    for lateral in (0.8, -0.8):
        smp = renderer.render_on_route(route, s, CAM, lateral_m=lateral)
        est = run(method, smp.image)
        assert est.found and np.sign(est.offset) == np.sign(lateral)
        assert abs(est.offset - smp.truth.offset) < 0.1  # truth: +-0.8 m / 3.2 m = +-0.25


@METHODS
@pytest.mark.parametrize("s", STRAIGHTS)
def test_heading_sign_follows_the_heading_offset(method, lane_loop, s):
    route, renderer = lane_loop
    for heading in (0.1, -0.1):
        smp = renderer.render_on_route(route, s, CAM, heading_offset=heading)
        est = run(method, smp.image)
        assert est.found and np.sign(est.heading) == np.sign(heading)
        assert abs(est.heading - smp.truth.heading) < 0.05


@METHODS
def test_debug_mask_marks_the_paint(method, lane_loop):
    route, renderer = lane_loop
    smp = renderer.render_on_route(route, 205.0, CAM)
    mask = run(method, smp.image).debug_mask
    assert mask.dtype == np.uint8 and mask.shape == smp.image.shape[:2] and set(np.unique(mask)) <= {0, 255}
    paint = cv2.dilate(smp.truth.marking_mask, np.ones((5, 5), np.uint8)) > 0
    on = mask > 0
    assert on.sum() > 200 and (on & paint).sum() / on.sum() > 0.8


@METHODS
def test_confidence_drops_when_one_side_is_gone(method, lane_loop):
    route, renderer = lane_loop
    confidence = []
    for s in STRAIGHTS:
        smp = renderer.render_on_route(route, s, CAM)
        both = run(method, smp.image)
        one_side = smp.image.copy()
        road = np.median(smp.image[200:, 140:180].reshape(-1, 3), axis=0)
        one_side[:, : CAM.width // 2] = road  # paint the left half over with plain road
        single = run(method, one_side)
        assert both.found and single.found and 0.0 < single.confidence <= 0.6 < both.confidence, s
        assert abs(single.offset - smp.truth.offset) < 0.1  # the right line and the width prior
        confidence.append(both.confidence)
    assert np.median(confidence) > 0.9, confidence




ALL_METHODS = pytest.mark.parametrize("name", ["canny-scan", "sliding-window", "color-hough", "vector-spline"])


@ALL_METHODS
@pytest.mark.parametrize("variant", ["robust", "published"])
def test_a_black_image_is_no_lane(name, variant):
    est = run(name, np.zeros((240, 320, 3), np.uint8), variant=variant)
    assert not est.found and est.confidence == 0.0
    assert est.debug_mask.shape == (240, 320) and not est.debug_mask.any()


@ALL_METHODS
@pytest.mark.parametrize("shape", [(1, 1, 3), (8, 12, 3), (20, 30, 3), (2, 200, 3), (48, 64), (120, 160, 3)])
def test_small_or_odd_images_do_not_crash(name, clean_frames, shape):
    img = np.full(shape, 90, np.uint8) if len(shape) == 2 else np.ascontiguousarray(
        clean_frames[0].image[: shape[0], : shape[1]])
    for variant in ("robust", "published"):
        est = run(name, img, variant=variant)
        assert est.debug_mask.shape == img.shape[:2]
        assert 0.0 <= est.confidence <= 1.0 and math.isfinite(est.offset)
