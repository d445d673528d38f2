"""color-hough (S3): offsets, signs and failure behaviour on seeded rendered frames."""

import cv2
import numpy as np
import pytest

from lane_helpers import CAM, DONKEY_STYLE, STRAIGHTS, loop_scene, run_method
from signlane import lanes
from signlane.camera import Camera
from signlane.lanes.color_hough import (ColorHoughParams, ColorHoughState, color_hough, ground_samples, merge_close,
                                        run_centres)
from signlane.types import LaneEstimate

METHOD = "color-hough"


def run(image, camera=CAM, variant="robust") -> LaneEstimate:
    return run_method(METHOD, image, camera, variant)


def test_nothing_credible_is_not_a_lane():
    black = run(np.zeros((240, 320, 3), np.uint8))
    assert not black.found and black.confidence == 0.0
    assert black.debug_mask.shape == (240, 320) and not black.debug_mask.any()
    assert not run(np.full((240, 320, 3), 128, np.uint8)).found


def test_gray_and_tiny_images(lane_loop):
    route, renderer = lane_loop
    smp = renderer.render_on_route(route, 105.0, CAM, lateral_m=0.5)
    gray = cv2.cvtColor(smp.image, cv2.COLOR_BGR2GRAY)
    for img in (gray, cv2.cvtColor(gray, cv2.COLOR_GRAY2BGR)):  # white paint needs no colour
        est = run(img)
        assert est.found and abs(est.offset - smp.truth.offset) < 0.1
    for shape in ((12, 16, 3), (1, 1, 3), (2, 3), (30, 40, 4)):
        for variant in ("robust", "published"):
            est = run(np.full(shape, 90, np.uint8), camera=None, variant=variant)
            assert isinstance(est, LaneEstimate) and est.debug_mask.shape == shape[:2]


def test_published_variant_is_the_source_and_runs():
    p = lanes.params_for(METHOD, "published")
    assert (p.yellow_lo, p.white_lo, p.white_hi[1]) == ((15, 40, 40), (0, 0, 200), 30)
    assert (p.canny_low, p.canny_high, p.hough_threshold, p.min_line_length, p.max_line_gap) == (200, 400, 10, 8, 8)
    # on the road it was written for (yellow left line, white right line), on every straight
    route, renderer = loop_scene(DONKEY_STYLE)
    for s in STRAIGHTS:
        for heading in (0.1, -0.1):
            smp = renderer.render_on_route(route, s, CAM, heading_offset=heading)
            est = run(smp.image, variant="published")
            assert isinstance(est, LaneEstimate) and est.method == METHOD and est.found
            assert np.sign(est.heading) == np.sign(heading) and abs(est.offset - smp.truth.offset) < 0.1, (s, heading)
            # the source looks for yellow on the left and white on the right, in the lower quarters
            assert not est.debug_mask[: CAM.height // 2].any()


def test_segments_across_the_road_are_dropped_and_double_strokes_merged():
    cam = Camera()
    along = cam.ground_to_image(np.array([[1.6, 3.0], [1.6, 8.0]])).ravel()
    across = cam.ground_to_image(np.array([[-1.0, 5.0], [1.0, 5.0]])).ravel()
    ys = np.linspace(2.0, 10.0, 33)
    pts, rows, clutter = ground_samples(np.array([along, across]), cam, ys, 0.7)
    assert np.allclose(pts[:, 0], 1.6, atol=1e-6) and 3.0 - 0.125 <= pts[:, 1].min() and pts[:, 1].max() <= 8.125
    assert 0.2 < clutter < 0.4  # 2 m across of 7 m in all
    double = np.array([[-1.8, 4.0], [-1.5, 4.0], [1.6, 4.0]])
    merged, mrows = merge_close(double, np.zeros(3, np.int64))
    assert np.allclose(merged[:, 0], [-1.65, 1.6]) and len(mrows) == 2


def test_run_centres_thin_each_run_to_one_pixel():
    mask = np.zeros((3, 20), np.uint8)
    mask[1, 2:7] = 255
    mask[1, 10:12] = 255
    out = run_centres(mask)
    assert list(np.flatnonzero(out[1])) == [4, 10] and not out[0].any() and not out[2].any()


def test_state_learns_the_lane_width_and_modes_are_checked(lane_loop):
    route, renderer = lane_loop
    smp = renderer.render_on_route(route, 205.0, CAM)
    est, state = color_hough(smp.image, CAM, ColorHoughParams(), None)
    assert isinstance(state, ColorHoughState) and abs(state.lane_width_m - 3.2) < 0.3
    with pytest.raises(ValueError, match="mode"):
        color_hough(smp.image, CAM, ColorHoughParams(mode="sideways"), None)
