"""The road's direction remembered over the last metres (signlane/road_heading.py)."""
import math

import numpy as np

from signlane.road_heading import LaneLateral, RoadHeading
from signlane.types import LaneEstimate


def _lane(heading: float, confidence: float = 1.0) -> LaneEstimate:
    return LaneEstimate("test", True, heading=heading, confidence=confidence, lane_width_m=3.2)


def test_a_misread_last_frame_does_not_turn_the_road():
    # the car drives north pointing 0.04 rad right of the road; the last frame (the junction's
    # mouth) misreads the heading as -0.035, as traced on painted via_town's central crossroads
    rh = RoadHeading()
    car = math.pi / 2
    for i in range(40):
        rh.add(0.2 * i, car, _lane(0.04 + 0.004 * math.sin(i)))
    rh.add(8.0, car, _lane(-0.035))
    assert abs(rh.car_heading(8.0, car) - 0.04) < 0.004


def test_in_a_gentle_bend_it_is_the_road_about_half_the_window_back_and_wraps_at_the_seam():
    # a bend of radius 100 m turning left: the road's direction grows 1/100 rad per metre, the car
    # following it 0.03 rad right of it. The median of the last 3 m is the road 1.5 m back; a
    # 25 m bend turns too much inside the window to have one direction
    for radius, expect in ((100.0, 0.03 - 1.5 / 100.0), (25.0, None)):
        rh = RoadHeading(window_m=3.0)
        for i in range(41):
            d = 0.2 * i
            rh.add(d, math.pi / 2 + d / radius - 0.03, _lane(0.03))
        got = rh.car_heading(8.0, math.pi / 2 + 8.0 / radius - 0.03)
        assert (got is None) if expect is None else abs(got - expect) < 0.003
    # straight on across the +-pi seam of the odometry frame
    rh = RoadHeading()
    for i in range(41):
        road = (math.pi - 0.02 + 0.001 * i + math.pi) % (2 * math.pi) - math.pi  # wraps to -pi at i = 20
        rh.add(0.2 * i, road - 0.02, _lane(0.02))
    assert abs(rh.car_heading(8.0, -math.pi + 0.02 - 0.02) - (0.02 - 0.0075)) < 0.002


def test_too_little_road_says_nothing_and_a_waiting_car_adds_one_sample():
    rh = RoadHeading()
    for i in range(5):
        rh.add(0.2 * i, 0.0, _lane(0.01))
    assert rh.car_heading(0.8, 0.0) is None  # 5 samples
    for i in range(200):  # stopped at a stop line: the odometer stands still
        rh.add(1.0, 0.0, _lane(0.01))
    assert rh.car_heading(1.0, 0.0) is None  # 6 samples over 1 m
    for i in range(30):  # unsure frames (no line found well) do not count
        rh.add(1.2 + 0.2 * i, 0.0, _lane(0.01, confidence=0.3))
    assert rh.car_heading(7.0, 0.0) is None
    for i in range(30):  # a lane with one line found, the other placed from it, does
        rh.add(7.2 + 0.2 * i, 0.0, _lane(0.01, confidence=0.5))
    assert abs(rh.car_heading(13.0, 0.0) - 0.01) < 1e-6
    # samples older than the window are forgotten
    rh = RoadHeading(window_m=3.0)
    for i in range(50):
        rh.add(0.2 * i, 0.0, _lane(0.05 if i < 30 else 0.0))
    assert abs(rh.car_heading(9.8, 0.0)) < 1e-6


def test_a_road_that_turned_inside_the_window_has_no_one_direction():
    # out of a lane shift just before a junction (VIA-style seed 13): the samples run from -38 to
    # +15 degrees; their median, -19, laid a right turn 34 degrees askew and the car hit the kerb
    rh = RoadHeading()
    for i, deg in enumerate(np.linspace(-38.0, 15.0, 25)):
        rh.add(0.12 * i, 0.0, _lane(math.radians(deg)))
    assert rh.car_heading(3.0, 0.0) is None
    # a steady road with one misread frame still answers
    rh = RoadHeading()
    for i in range(25):
        rh.add(0.12 * i, 0.0, _lane(math.radians(6.0 + 0.3 * math.sin(i)) if i < 24 else math.radians(-2.3)))
    assert abs(math.degrees(rh.car_heading(3.0, 0.0)) - 6.0) < 0.4


def test_a_misread_last_frame_does_not_move_where_a_junction_path_starts():
    # the lane's centre 0.1 m left of the car, read frame after frame; on the last frame (the
    # junction's mouth, a random look in shadow) a 2.2 m "lane" puts it 1.2 m right
    ll = LaneLateral()
    for i in range(12):
        ll.add(0.15 * i, LaneEstimate("test", True, offset=0.1 / 3.2, lane_width_m=3.2))
    ll.add(1.8, LaneEstimate("test", True, offset=-1.2 / 2.2, lane_width_m=2.2))
    assert abs(ll.lateral_m(1.8) + 0.1) < 1e-6
    # frames left behind the window no longer count; too few recent ones say nothing
    assert ll.lateral_m(1.8 + 3.0) is None
    ll.add(10.0, LaneEstimate("test", False))
    assert ll.lateral_m(10.0) is None


def test_a_run_of_misread_frames_does_not_move_where_a_junction_path_starts():
    # traced on a random look: at a crossing's mouth the paint method took the side road's lines
    # for the lane, 1-1.2 lane widths right, on the frames of the last 1.2 m: most of the window
    def lane(centre_m: float) -> LaneEstimate:
        return LaneEstimate("test", True, offset=-centre_m / 3.5, lane_width_m=3.5)

    ll, odo = LaneLateral(), [0.1 * i for i in range(43)]
    for d in odo[:31]:
        ll.add(d, lane(-0.1))
    for d in odo[31:]:
        ll.add(d, lane(3.5 + 0.7 * math.sin(d)))
    assert abs(ll.lateral_m(odo[-1]) + 0.1) < 1e-6
    # without leaving them out, their median is where the path would start, metres right
    free = LaneLateral(max_jump_m=99.0)
    for d in odo:
        free.add(d, lane(-0.1) if d < odo[31] else lane(3.5 + 0.7 * math.sin(d)))
    assert free.lateral_m(odo[-1]) > 2.5
    # a car that drifts sideways as a car can (0.4 m per metre driven) is followed
    drift = LaneLateral()
    for d in odo:
        drift.add(d, lane(0.4 * d))
    assert abs(drift.lateral_m(odo[-1]) - 0.4 * 3.2) < 0.15
