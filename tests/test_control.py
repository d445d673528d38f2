"""Steering controllers: signs of the command and the source controllers' published rules."""
import math

import numpy as np
import pytest

from signlane.camera import Camera
from signlane.control import CONTROLLERS, S3Smoothed, centre_x_at, make_controller
from signlane.lanes.geometry import Boundary, estimate_from_fits
from signlane.types import LaneEstimate


def lane_from(offset_m: float = 0.0, slope: float = 0.0, a: float = 0.0, cam: Camera = Camera()) -> LaneEstimate:
    """A lane whose centre is x(y) = -offset_m + slope*y + a*y^2 (car frame), 3.2 m wide."""
    left = Boundary(np.array([a, slope, -offset_m - 1.6]), (1.0, 25.0), 50)
    right = Boundary(np.array([a, slope, -offset_m + 1.6]), (1.0, 25.0), 50)
    return estimate_from_fits("test", cam, left, right, 3.2)


def test_estimate_conventions():
    est = lane_from(offset_m=0.64)  # lane centre 0.64 m left of the car: car is right of centre
    assert est.offset == pytest.approx(0.2)
    assert lane_from(slope=-0.1).heading == pytest.approx(math.atan(0.1))  # lane goes left: car points right
    assert lane_from(a=0.01).curvature > 0  # bends right
    assert centre_x_at(est, 0.0) == pytest.approx(-0.64)


@pytest.mark.parametrize("name", sorted(CONTROLLERS))
def test_every_controller_steers_back_to_the_lane_centre(name):
    c = make_controller(name, Camera())
    assert c.step(lane_from(offset_m=0.8)) < -0.01  # right of centre -> steer left
    c.reset()
    assert c.step(lane_from(offset_m=-0.8)) > 0.01
    c.reset()
    assert abs(c.step(lane_from())) < 0.02  # centred and straight -> straight


@pytest.mark.parametrize("name", ["pure-pursuit", "s1-proportional", "s3-atan"])
def test_controllers_correct_heading(name):
    c = make_controller(name, Camera())
    assert c.step(lane_from(slope=-0.15)) < -0.01  # pointing right of the lane -> steer left


@pytest.mark.parametrize("name", ["pure-pursuit", "s3-atan"])
def test_controllers_that_look_ahead_follow_a_bend(name):
    # (S1 measures one row near the car, where a bend has not moved the lane yet)
    c = make_controller(name, Camera())
    assert c.step(lane_from(a=0.02)) > 0.01  # bend right -> steer right


def test_pure_pursuit_matches_the_bicycle_model_on_a_circle():
    c = make_controller("pure-pursuit")
    k = 1 / 20.0  # a 20 m right-hand bend, car centred and aligned
    steer = c.step(LaneEstimate("test", True, curvature=k, lane_width_m=3.2))
    wheel = math.degrees(math.atan(1.8 * k)) / 25.0  # the wheel angle that drives that circle
    assert steer == pytest.approx(wheel, rel=0.05)


def test_pure_pursuit_aims_at_the_fitted_centre_at_a_bends_entry():
    # A lane seen from 3.4 m (VIA's camera) pointing a little left at the car and bending right
    # hard further on, as at the entry of a 12 m bend: the slope is near 0 at the car and steep
    # 8 m out. Rebuilt from offset, heading and the curvature 8 m out, its centre came out at
    # half its true lateral distance there and the car ran wide (off the road on loop_demo).
    a, b = 0.063, -0.29
    left = Boundary(np.array([a, b, -1.2]), (3.4, 11.4), 50)
    right = Boundary(np.array([a, b, 2.0]), (3.4, 11.4), 50)
    lane = estimate_from_fits("test", Camera(640, 480), left, right, 3.2)
    ld = 7.5
    true_x = float(np.polyval([a, b, 0.4], ld))  # the fitted centre at the lookahead: 1.77 m
    assert abs(centre_x_at(lane, ld) - true_x) > 0.5  # what the old rebuild aimed at
    c = make_controller("pure-pursuit")
    c.lookahead, c.per_mps = ld, 0.0
    aim = c.steer_to(true_x, ld)
    assert c.step(lane) == pytest.approx(aim, rel=0.05)
    assert c.step(lane) > 0.2  # a firm right turn, not the old one of about 0.1


def test_s1_proportional_uses_the_published_gain():
    cam = Camera(640, 480)
    c = make_controller("s1-proportional", cam)
    # 0.01 per bird's-eye pixel; S1's bird's-eye maps the bottom row (ground width w) to W/4 px
    ends = cam.image_to_ground(np.array([[0.0, 479.0], [639.0, 479.0]]))
    px_per_m = 160.0 / np.hypot(*(ends[1] - ends[0]))
    assert c.step(lane_from(offset_m=-0.5, cam=cam)) == pytest.approx(min(1.0, 0.01 * px_per_m * 0.5), rel=0.02)


def test_s3_smoothed_limits_the_change_per_frame():
    c = S3Smoothed(Camera())
    first = c.step(lane_from(offset_m=-3.0))  # a big jump to the right
    assert first * 45 == pytest.approx(5.0, abs=1e-6)  # two lines: at most 5 degrees a frame
    for _ in range(20):
        last = c.step(lane_from(offset_m=-3.0))
    assert last * 45 <= 35.0 + 1e-6


def test_lost_lane_fades_to_straight():
    c = make_controller("pure-pursuit")
    c.step(lane_from(offset_m=-1.0))
    lost = LaneEstimate("test", False)
    values = [c.step(lost) for _ in range(10)]
    assert abs(values[-1]) < abs(values[0])
