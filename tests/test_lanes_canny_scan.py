"""canny-scan (S1): offsets, signs and failure behaviour on seeded rendered frames."""
import math

import cv2
import numpy as np
import pytest

from lane_helpers import CAM, run_method
from signlane import lanes
from signlane.camera import Camera
from signlane.lanes.association import ego_lane
from signlane.lanes.canny_scan import CannyScanParams, CannyScanState, canny_scan, published_birdseye
from signlane.types import LaneEstimate

METHOD = "canny-scan"


def run(image, camera=CAM, variant="robust") -> LaneEstimate:
    return run_method(METHOD, image, camera, variant)


def test_nothing_credible_is_not_a_lane():
    black = run(np.zeros((240, 320, 3), np.uint8))
    assert not black.found and black.confidence == 0.0
    assert black.debug_mask.shape == (240, 320) and not black.debug_mask.any()
    flat = run(np.full((240, 320, 3), 128, np.uint8))
    assert not flat.found
    noise = [run(np.random.default_rng(k).integers(0, 256, (240, 320, 3), dtype=np.uint8)).found for k in range(5)]
    assert sum(noise) <= 1


def test_gray_and_tiny_images(lane_loop):
    route, renderer = lane_loop
    smp = renderer.render_on_route(route, 105.0, CAM, lateral_m=0.5)
    gray = cv2.cvtColor(smp.image, cv2.COLOR_BGR2GRAY)
    for img in (gray, cv2.cvtColor(gray, cv2.COLOR_GRAY2BGR)):
        est = run(img)
        assert est.found and abs(est.offset - smp.truth.offset) < 0.1
    for shape in ((12, 16, 3), (1, 1, 3), (2, 3), (30, 40, 4)):
        for variant in ("robust", "published"):
            est = run(np.full(shape, 90, np.uint8), camera=None, variant=variant)
            assert isinstance(est, LaneEstimate) and est.debug_mask.shape == shape[:2]


def test_published_variant_is_the_source_and_scans_one_row(lane_loop):
    p = lanes.params_for(METHOD, "published")
    assert (p.blur_px, p.canny_low, p.canny_high, p.scan_row_frac, p.top_row_frac) == (11, 150.0, 200.0, 0.9, 0.4)
    route, renderer = lane_loop
    for lateral in (0.8, -0.8):
        smp = renderer.render_on_route(route, 205.0, CAM, lateral_m=lateral)
        est = run(smp.image, variant="published")
        assert isinstance(est, LaneEstimate) and est.method == METHOD
        assert est.found and np.sign(est.offset) == np.sign(lateral) and abs(est.offset - smp.truth.offset) < 0.1
        assert est.heading == 0.0 and est.curvature == 0.0  # one row: straight-ahead boundaries


def test_published_birdseye_comes_from_the_camera():
    cam = Camera(pitch_deg=20.0)  # the row at 0.4*H is well below the horizon
    bev = published_birdseye(cam)
    assert bev.size == (cam.width, cam.height)
    g = cam.image_to_ground(np.array([[cam.width / 2, cam.height], [cam.width / 2, 0.4 * cam.height]]))
    uv = bev.ground_to_bev(g)
    assert np.allclose(uv[:, 1], [cam.height, 0.0], atol=0.5) and np.allclose(uv[:, 0], cam.width / 2, atol=0.5)
    # a camera looking nearly level: the 0.4*H row is at the horizon, so a row below it is used
    low = published_birdseye(Camera(pitch_deg=3.0))
    assert math.isfinite(low.y_range_m[1]) and low.y_range_m[1] < 200.0


def test_state_learns_the_lane_width_and_modes_are_checked(lane_loop):
    route, renderer = lane_loop
    smp = renderer.render_on_route(route, 205.0, CAM)
    est, state = canny_scan(smp.image, CAM, CannyScanParams(), None)
    assert isinstance(state, CannyScanState) and abs(state.lane_width_m - 3.2) < 0.3
    with pytest.raises(ValueError, match="mode"):
        canny_scan(smp.image, CAM, CannyScanParams(mode="sideways"), None)


def test_far_road_edge_stands_in_for_a_missing_centre_line():
    # ground points: the right edge line at x=+1.6 and the road's far edge two lanes left (x=-4.8)
    ys = np.linspace(2.0, 10.0, 30)
    pts = np.concatenate([np.column_stack([np.full(30, 1.6), ys]), np.column_stack([np.full(30, -4.8), ys])])
    rows = np.concatenate([np.arange(30), np.arange(30)])
    lane = ego_lane(pts, rows, 30, 3.2)
    assert lane.measured and abs(lane.width_m - 3.2) < 0.05
    assert abs(lane.left.x_at(0.0) + 1.6) < 0.05 and abs(lane.right.x_at(0.0) - 1.6) < 0.05
