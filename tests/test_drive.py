"""Driving: the car model, odometry, junction perception, the behaviour's rules, and short
closed-loop drives in the local simulator (a lap; a stop at a stop sign)."""
import math

import numpy as np
import pytest

from signlane import lanes
from track_helpers import track_with_stop_sign
from signlane.behaviour import Behaviour, _junction_path, _rotate, BehaviourParams
from signlane.camera import via_camera
from signlane.config import Config
from signlane.control import PurePursuit, path_bend_towards
from signlane.junction import JunctionDetector, JunctionParams, JunctionView, Opening, view_from_scan
from signlane.odometry import OdoPose, Odometry
from signlane.sim.driver import Driver
from signlane.sim.simulator import SimConfig, Simulator, run_inprocess
from signlane.sim.vehicle import Vehicle
from signlane.types import LaneEstimate
from signlane.world.effects import Effects
from signlane.world.procedural import generate_map
from signlane.world.render import Renderer
from signlane.world.route import Pose, Route, random_policy
from signlane.world.scene import build_scene
from signlane.world.maps import load_track
from signlane.world.track import RoadStyle, Track


FRAME = 1 / 30  # VIA's usual frame period


def drive(car: Vehicle, seconds: float, steering: float | None, throttle: float = 0.0, dt: float = FRAME) -> list:
    """Step the car frame by frame, replying (steering, throttle) every frame (None: no replies);
    the speed after each frame."""
    speeds = []
    for _ in range(round(seconds / dt)):
        if steering is not None:
            car.command(steering, throttle)
        car.step(dt)
        speeds.append(car.speed)
    return speeds


def test_half_pedal_accelerates_at_vias_rate_after_the_traction_ramp():
    car = Vehicle(Pose(0.0, 0.0, math.pi / 2))
    p = car.params
    assert p.full_accel_mps2 / 2 == pytest.approx(1.422, abs=1e-3)  # 125 N m on 4 wheels of 0.335/0.37 m, 1 t
    v = drive(car, 1.0, 0.0, 1.0)
    assert car.pedal == 0.5 and car.ticks == 50
    assert v[-1] == pytest.approx(0.675, abs=0.02)  # the ramp: on average half of 1.42 m/s^2, less drag
    v = drive(car, 2.0, 0.0, 1.0)
    mean_speed = (v[0] + v[-1]) / 2
    assert (v[-1] - v[0]) / (2.0 - FRAME) == pytest.approx(1.422 - 0.1 * mean_speed, abs=0.01)  # minus drag
    drive(car, 30.0, 0.0, 1.0)
    assert car.speed == pytest.approx(30 * 0.44704)  # the 30 mph cap


def test_throttle_is_a_target_fraction_held_bang_bang():
    car = Vehicle(Pose(0.0, 0.0, math.pi / 2))
    speeds = np.array(drive(car, 25.0, 0.0, 0.5))
    held = speeds[-300:]  # the last 10 s
    assert held.mean() == pytest.approx(0.5 * 13.4112, abs=0.05) and np.ptp(held) < 0.15
    assert car.pedal in (0.0, 0.5)


def test_coasting_stops_the_car_without_brakes():
    car = Vehicle(Pose(0.0, 0.0, math.pi / 2), speed=5.0)
    speeds = drive(car, 10.0, 0.0, 0.0)
    assert car.pedal == 0.0 and car.speed == 0.0
    # dv/dt = -(0.5 + 0.1 v): 15.34 m and 6.9 s from 5 m/s
    assert car.odometer_m == pytest.approx(50 - 50 * math.log(2), abs=0.15)
    assert (np.array(speeds) > 0).sum() * FRAME == pytest.approx(6.9, abs=0.1)
    assert all(b <= a for a, b in zip(speeds, speeds[1:]))  # no reverse, no creep


def test_pedal_and_wheels_persist_without_new_replies():
    car = Vehicle(Pose(0.0, 0.0, math.pi / 2))
    car.command(0.4, 0.2)  # one reply: target 2.68 m/s, below it, so half pedal
    drive(car, 5.0, None)
    assert car.pedal == 0.5 and car.wheel_deg == pytest.approx(10.0)
    assert car.speed > 0.2 * 13.4112 + 1.0  # nothing re-evaluated the pedal: it passed its target
    car.command(0.0, 0.2)  # now above the target: the pedal comes off and stays off
    drive(car, 4.0, None)
    assert car.pedal == 0.0 and car.speed < 2.0  # even once below 2.68 m/s again, with no new reply


def test_a_reply_takes_effect_at_the_next_physics_tick():
    car = Vehicle(Pose(0.0, 0.0, math.pi / 2))
    car.command(1.0, 0.5)
    car.step(0.01)  # half a tick: nothing happens yet
    assert (car.ticks, car.wheel_deg, car.pedal) == (0, 0.0, 0.0)
    car.command(-0.5, 0.5)  # a newer reply before the tick replaces it
    car.step(0.01)
    assert (car.ticks, car.wheel_deg, car.pedal) == (1, -12.5, 0.5)
    ticks = []
    for _ in range(6):  # 30 frames/s: 1 or 2 ticks a frame, the remainder carried
        before = car.ticks
        car.step(FRAME)
        ticks.append(car.ticks - before)
    assert ticks == [1, 2, 2, 1, 2, 2]  # 10 ticks in 0.2 s
    drive(car, 1.0, 0.0, 0.5, dt=1 / 60)
    assert car.ticks == 11 + 50  # 60 frames/s: some frames have no tick at all


def test_positive_steering_turns_right_at_vias_minimum_radius():
    car = Vehicle(Pose(0.0, 0.0, math.pi / 2))
    car.command(5.0, 0.2)  # clamped to full right lock
    car.step(FRAME)
    assert car.wheel_deg == 25.0
    xy = []
    for _ in range(200):
        car.command(1.0, 0.2)
        car.step(FRAME)
        xy.append((car.pose.x, car.pose.y))
    assert car.pose.heading < math.pi / 2 - 2.0  # heading (CCW) decreases: a right turn
    xy = np.array(xy[60:])  # on the circle at a steady speed: fit its centre and radius
    A = np.column_stack([2 * xy, np.ones(len(xy))])
    cx, cy, c = np.linalg.lstsq(A, (xy ** 2).sum(1), rcond=None)[0]
    radius = math.sqrt(c + cx ** 2 + cy ** 2)
    assert radius == pytest.approx(1.957 / math.tan(math.radians(25)), abs=0.02)  # 4.20 m at the rear axle
    assert cx > 0  # the circle's centre is to the right of the start (east, the car set off north)
    car.command(-1.0, 0.2)
    car.step(FRAME)
    assert car.wheel_deg == -25.0


def test_odometry_follows_the_car_round_a_bend():
    car, odo = Vehicle(Pose(0.0, 0.0, math.pi / 2)), Odometry(1.957)
    t = 0.0
    for k in range(180):
        car.command(0.6 if k > 60 else 0.0, 0.4)
        car.step(FRAME)
        t += FRAME
        pose = odo.step(t, car.speed, car.wheel_deg)
    assert car.pose.heading < math.pi / 2 - 1.0  # it did turn
    assert math.hypot(pose.x - car.pose.x, pose.y - car.pose.y) < 0.05 * car.odometer_m
    assert abs(pose.heading - car.pose.heading) < 0.1


def test_exit_choice_follows_signs_and_keeps_straight_when_it_can():
    b = Behaviour()
    assert b.choose({"left", "right", "straight"}, None) == "straight"
    assert b.choose({"left", "right"}, None) == "right"
    assert b.choose({"left", "right", "straight"}, "left") == "left"
    assert b.choose({"left", "straight"}, "no_left") == "straight"
    assert b.choose({"left", "right"}, "no_right") == "left"
    assert b.choose({"right", "straight"}, "left") == "straight"  # no such exit: ignore the sign


def test_signs_side_by_side_stay_two_signs_and_a_changed_class_replaces_the_old_one():
    b = Behaviour()
    stop, turn = np.array([3.0, 12.0]), np.array([3.0, 14.0])
    for frame in range(3):  # a stop sign and a turn sign 2 m apart, seen together, either order
        b.observe_signs([("right", turn + 0.1 * frame), ("stop", stop)] if frame % 2 else [("stop", stop), ("right", turn)])
    assert sorted(m.label for m in b.signs) == ["right", "stop"]
    assert np.allclose(next(m for m in b.signs if m.label == "stop").pos, stop)
    b = Behaviour()
    b.observe_signs([("left", stop)])
    b.observe_signs([("no_left", stop + 0.5)])  # the same sign, confirmed from closer as another class
    assert [m.label for m in b.signs] == ["no_left"]


def test_junction_paths_end_on_the_exit_lane():
    p = BehaviourParams()
    right, left = _junction_path("right", 14.0, 0.0, p), _junction_path("left", 14.0, 0.0, p)
    assert right[-1, 1] == pytest.approx(14.0 - 1.6) and right[-1, 0] > 10  # heading right, exit lane near side
    assert left[-1, 1] == pytest.approx(14.0 + 1.6) and left[-1, 0] < -10
    assert np.all(np.diff(_junction_path("straight", 14.0, 0.2, p)[:, 1]) > 0)


def _approach(b: Behaviour, lane: LaneEstimate, near: float, cut: bool = False, frames: int = 4) -> str:
    """Drive a Behaviour towards a lone right opening (the road straight on ending), the car
    moving 0.5 m a frame with the opening `near` m ahead at the last; its last state."""
    state = ""
    for i in range(frames):
        n = near + 0.5 * (frames - 1 - i)
        view = JunctionView(None, Opening(n, n + 7.0, True, dead=False, cut=cut), False, straight_dead=True)
        state = b.step(0.1 * i, OdoPose(0.0, 0.5 * i), 0.5 * i, 4.0, lane, view)[2]
    return state


def test_a_lone_opening_the_lane_bends_toward_is_a_bend_not_a_forced_turn():
    # A right bend shows the junction detector an opening on its inner side and the road ending
    # on its outer one: planned as a forced turn with a junction's tight radius, the car cut a
    # 13 m bend and left the road. At a junction the lane runs straight up to it.
    ys = np.arange(3.5, 12.0, 0.5)
    straight = LaneEstimate("test", True, lane_width_m=3.2, path_m=np.column_stack([np.zeros_like(ys), ys]))
    bending = LaneEstimate("test", True, curvature=1 / 13, lane_width_m=3.2,
                           path_m=np.column_stack([ys ** 2 / 26.0, ys]))
    assert _approach(Behaviour(), straight, 10.0) == "junction-right"
    assert _approach(Behaviour(), bending, 10.0) != "junction-right"
    mirrored = LaneEstimate("test", True, curvature=-1 / 13, lane_width_m=3.2,
                            path_m=np.column_stack([-ys ** 2 / 26.0, ys]))
    assert _approach(Behaviour(), mirrored, 10.0) == "junction-right"  # bending away: still the junction


def test_near_a_junction_a_way_judged_dead_is_taken_when_the_sign_leaves_no_other():
    # A "no right" T reached along its stem on a random look (VIA's style, seed 13 and via_town):
    # its left arm read dead on every frame, so the only exit was the banned right; the car
    # turned right. The sign says the left arm is there: close to the junction it is taken.
    ys = np.arange(3.5, 12.0, 0.5)
    lane = LaneEstimate("test", True, lane_width_m=4.0, path_m=np.column_stack([np.zeros_like(ys), ys]))
    for first_near, dead_from in ((13.0, 0), (9.0, 1)):
        # judged dead from afar (planned only once near), or only after a plan made while it read open
        # (planned again once it reads dead: with the sign still, which the first plan had used up)
        b = Behaviour()
        b.observe_signs([("no_right", np.array([2.5, first_near - 2.0]))])
        states = []
        for i in range(int((first_near - 5.5) / 0.5) + 1):
            n = first_near - 0.5 * i
            view = JunctionView(Opening(n, n + 4.0, True, dead=i >= dead_from), Opening(n, n + 4.0, True, dead=False),
                                False, straight_dead=True)
            states.append(b.step(0.1 * i, OdoPose(0.0, 0.5 * i), 0.5 * i, 4.0, lane, view, two_lane=False)[2])
        assert {d["turn"] for d in b.decisions} == {"left"}, b.decisions
        if dead_from == 0:
            assert b.decisions[0]["near_m"] <= BehaviourParams().commit_late_m  # not planned while far
        assert states[-1] == "junction-left"


def test_straight_on_past_an_opening_inside_a_gentle_painted_bend_follows_the_lane():
    # A 50 m left bend on a random look: its inside read as a left opening (the painted
    # detector's bands run straight ahead), the road on as straight on; the car planned the
    # crossing straight, followed a path laid straight along itself, and left its lane 2 m
    # wide of the bend. Past a real crossing on a straight road the path stays.
    ys = np.arange(3.5, 14.0, 0.5)
    straight = LaneEstimate("test", True, lane_width_m=3.2, path_m=np.column_stack([np.zeros_like(ys), ys]))
    bending = LaneEstimate("test", True, curvature=-1 / 50, lane_width_m=3.2,
                           path_m=np.column_stack([-ys ** 2 / 100.0, ys]))
    for lane, planned in ((straight, True), (bending, False)):
        b = Behaviour()
        states = []
        for i in range(4):
            n = 11.0 - 0.5 * i
            view = JunctionView(Opening(n, n + 5.0, True, dead=False), None, True, straight_dead=False)
            states.append(b.step(0.1 * i, OdoPose(0.0, 0.5 * i), 0.5 * i, 4.0, lane, view)[2])
        assert [d["turn"] for d in b.decisions] == ["straight"]
        assert (states[-1] == "junction-straight") == planned
        assert (b.path is not None) == planned


def test_straight_on_past_a_lone_opening_where_a_bends_lane_was_just_lost_follows_the_lane():
    # random looks, painted, traced (seeds 3 and 10): a bend's lane lost on the frames its inside,
    # read as an opening with the road going on, was planned straight on; the path laid straight
    # along the car left the road. A lane lost before a crossing on a straight road keeps the path,
    # as does a bend's without the memory of it (bend_memory_m 0).
    ys = np.arange(3.5, 14.0, 0.5)
    bending = LaneEstimate("test", True, curvature=0.05, lane_width_m=3.2,
                           path_m=np.column_stack([0.025 * ys ** 2, ys]))
    lost = LaneEstimate("test", False)
    for params, before, planned in ((BehaviourParams(), _straight_lane(3.2), True), (BehaviourParams(), bending, False),
                                    (BehaviourParams(bend_memory_m=0.0), bending, True)):
        b = Behaviour(params)
        for i in range(6):  # 1.8 m of lane, then the frames at the opening, no lane found
            b.step(0.1 * i, OdoPose(0.0, 0.3 * i), 0.3 * i, 3.0, before, None)
        for i in range(6, 9):
            n = 8.0 - 0.3 * (i - 6)
            view = JunctionView(None, Opening(n, n + 4.0, True, dead=False), True, straight_dead=False)
            b.step(0.1 * i, OdoPose(0.0, 0.3 * i), 0.3 * i, 3.0, lost, view)
        assert [d["turn"] for d in b.decisions] == ["straight"]
        assert (b.path is not None) == planned


def test_a_lone_opening_in_a_bend_is_a_bend_even_off_the_lanes_middle():
    # Left of the lane's middle in an S (1.0 m on seed 0's painted track), the line traced
    # ahead in an 18 m right bend reads short of the bend as the car would steer to it: taken
    # alone, the bend's outer side was planned as a forced right turn and the car left the road.
    # The lane's own fitted curvature still says bend.
    ys = np.arange(3.5, 12.0, 0.5)
    off_middle = np.column_stack([-1.0 + ys ** 2 / 36.0, ys])
    assert path_bend_towards(off_middle, BehaviourParams().curve_preview_m, 1.0) < BehaviourParams().bend_not_junction
    lane = LaneEstimate("test", True, curvature=1 / 18, lane_width_m=3.2, path_m=off_middle)
    assert _approach(Behaviour(), lane, 10.0) != "junction-right"


def test_a_bend_beyond_the_end_of_a_lane_shift_is_still_a_bend():
    # Out of a lane shift straight into a right bend: the near part of the traced lane still
    # bends left (the shift's last arc), its far part right. Its sharpest point is the left one,
    # which hid the bend: the car planned a forced turn of a junction's radius and cut the bend.
    ys = np.arange(3.5, 12.0, 0.5)
    x = np.where(ys < 6.0, -ys ** 2 / 30.0, -1.2 - 0.4 * (ys - 6.0) + (ys - 6.0) ** 2 / 4.0)
    s_bend = LaneEstimate("test", True, curvature=-0.05, lane_width_m=3.2, path_m=np.column_stack([x, ys]))
    k = 2 * x / (x ** 2 + ys ** 2)
    assert -k.min() > k.max() > BehaviourParams().bend_not_junction  # the left part is the sharpest
    assert _approach(Behaviour(), s_bend, 10.0) != "junction-right"


@pytest.mark.parametrize("first_near", [11.0, 7.0])
def test_a_turn_sign_whose_exit_comes_into_view_late_is_obeyed(first_near):
    # A crossroads whose right arm shows a few frames after the left one, with a "right" sign.
    # Still far from it (11 m), the junction is not planned until the right arm is seen: the
    # sign says a way is there. Planned once it is close (within commit_late_m) with the left and
    # straight exits only, the sign could not be obeyed; once the right arm is seen (the car
    # still short of the junction) the plan is made again, and the sign still holds.
    ys = np.arange(3.5, 12.0, 0.5)
    lane = LaneEstimate("test", True, lane_width_m=4.0, path_m=np.column_stack([np.zeros_like(ys), ys]))
    b = Behaviour()
    b.observe_signs([("right", np.array([3.0, first_near - 2.0]))])
    states = []
    for i in range(6):
        n = first_near - 0.5 * i
        right = Opening(n, n + 4.0, True, dead=False) if i >= 3 else None
        view = JunctionView(Opening(n, n + 4.0, True, dead=False), right, True, straight_dead=False)
        states.append(b.step(0.1 * i, OdoPose(0.0, 0.5 * i), 0.5 * i, 4.0, lane, view, two_lane=False)[2])
    expect = ["right"] if first_near - 1.0 > BehaviourParams().commit_late_m else ["straight", "right"]
    assert [d["turn"] for d in b.decisions] == expect
    assert all(d["sign"] == "right" for d in b.decisions)
    assert states[-1] == "junction-right"


def test_a_no_turn_sign_at_a_junction_read_with_only_the_banned_way_waits_for_a_better_look():
    # A T reached along its stem under a "no right" sign, on a random look: on the frame its
    # right arm came near, its left arm was unseen and straight on read dead, and the only exit
    # was the banned one: the car turned right. Far from the junction, it now reads it again
    # on the next frames, and turns left once the left arm shows.
    ys = np.arange(3.5, 12.0, 0.5)
    lane = LaneEstimate("test", True, lane_width_m=3.2, path_m=np.column_stack([np.zeros_like(ys), ys]))
    b = Behaviour()
    b.observe_signs([("no_right", np.array([2.5, 9.0]))])
    states = []
    for i in range(4):
        n = 10.0 - 0.5 * i
        left = Opening(n, n + 4.0, True, dead=False) if i >= 2 else None
        view = JunctionView(left, Opening(n, n + 4.0, True, dead=False), False, straight_dead=True)
        states.append(b.step(0.1 * i, OdoPose(0.0, 0.5 * i), 0.5 * i, 4.0, lane, view)[2])
    assert [d["turn"] for d in b.decisions] == ["left"]
    assert states[2:] == ["junction-left", "junction-left"] and not any(s.startswith("junction") for s in states[:2])


def test_a_lane_lost_in_a_bend_is_followed_along_the_line_last_traced():
    # In a tight bend the road leaves the view sideways and the lane is lost: drifting back to
    # straight from there took the car over the bend's outer kerb. It keeps to the centre line
    # it last saw (odometry frame) while that is ahead, then drifts straight.
    r = 6.0  # a left bend of VIA's 2x2 turn
    ys = np.arange(0.5, 5.9, 0.25)
    bend = LaneEstimate("test", True, lane_width_m=4.0, path_m=np.column_stack([-(r - np.sqrt(r * r - ys ** 2)), ys]))
    lost = LaneEstimate("test", False)
    b = Behaviour()
    seen = b.step(0.0, OdoPose(0.0, 0.0), 0.0, 3.0, bend, None, two_lane=False)[0]
    steer = [b.step(0.1 * i, OdoPose(0.0, 0.3 * i), 0.3 * i, 3.0, lost, None, two_lane=False)[0] for i in range(1, 6)]
    assert seen < -0.2 and all(s < 0.7 * seen for s in steer)  # still turning left, more as the line curves on
    later = [b.step(1.0 + 0.1 * i, OdoPose(0.0, 12.0 + i), 12.0 + i, 3.0, lost, None, two_lane=False)[0] for i in range(15)]
    assert abs(later[-1]) < 0.1 * abs(seen)  # past its end: back to straight


def test_an_opening_whose_near_end_is_outside_the_view_is_planned_once_in_view():
    # VIA's camera shows a painted road's left strip from about 12 m on, so an opening there
    # begins at the view's edge (12.1 m on one lap) and never came nearer than commit_near_m
    ys = np.arange(3.5, 12.0, 0.5)
    lane = LaneEstimate("test", True, lane_width_m=3.2, path_m=np.column_stack([np.zeros_like(ys), ys]))
    assert _approach(Behaviour(), lane, 12.1) != "junction-right"
    assert _approach(Behaviour(), lane, 12.1, cut=True) == "junction-right"
    assert _approach(Behaviour(), lane, 16.0, cut=True) != "junction-right"  # not yet: too far to plan


def test_a_turn_taken_as_the_least_dead_way_is_not_planned_again_every_frame():
    # A T reached along its stem whose two arms were both judged dead (a lane shift one tile on
    # looks like the long arm ending): the least dead way is taken, and judging it dead again
    # on the next frame is no news; the plan was made again on every frame to the junction.
    ys = np.arange(3.5, 12.0, 0.5)
    lane = LaneEstimate("test", True, lane_width_m=4.0, path_m=np.column_stack([np.zeros_like(ys), ys]))
    b = Behaviour()
    for i in range(8):
        n = 10.0 - 0.25 * i
        view = JunctionView(Opening(n, n + 4.0, True, dead=True), Opening(n, n + 4.0, True, dead=True), False,
                            straight_dead=True)
        state = b.step(0.05 * i, OdoPose(0.0, 0.25 * i), 0.25 * i, 3.0, lane, view, two_lane=False)[2]
    # planned once, and once more when the second frame made both arms dead: then it holds
    assert [d["turn"] for d in b.decisions] == ["right", "right"] and state == "junction-right"


def test_of_two_arms_judged_dead_on_every_frame_the_one_judged_so_less_often_is_taken():
    # A T reached along its stem with the car askew out of a bend (the pilot on VIA seed 106):
    # its stub read dead on 8 frames, its long arm, mostly beyond the view, on 2. Both wholly
    # dead, they tied and the stub (right before left) was taken, into its end.
    b = Behaviour()
    for i in range(8):
        n = 12.0 - 0.25 * i
        view = JunctionView(Opening(n, n + 4.0, True, dead=True if i in (2, 5) else None),
                            Opening(n, n + 4.0, True, dead=True), False, straight_dead=True)
        state = b.step(0.05 * i, OdoPose(0.0, 0.25 * i), 0.25 * i, 3.0, _straight_lane(), view, two_lane=False)[2]
    assert b._votes["left"] == [2, 0] and b._votes["right"] == [8, 0]
    assert state == "junction-left" and b.decisions[-1]["exits"] == ["left"]


def test_out_of_a_kerbed_turn_the_exit_roads_lane_takes_over_from_the_planned_tail():
    # The planned turn's straight tail ran on 12 m out of its arc: one tile on, the exit road
    # shifted sideways (a lane shift) and the car, still on its tail, touched the kerb. Past
    # the arc, inside the exit road's edges, the carriageway's lane leads on.
    ys = np.arange(3.5, 12.0, 0.5)
    lane = LaneEstimate("test", True, lane_width_m=4.0, path_m=np.column_stack([np.zeros_like(ys), ys]))
    lost = LaneEstimate("test", False)

    def turned(exit_lane):
        b = Behaviour()
        for i in range(3):  # a T reached along its stem, its right arm a stub: a forced left
            view = JunctionView(Opening(6.0, 10.0, True, dead=False), Opening(6.0, 10.0, True, dead=True), False,
                                straight_dead=True)
            state = b.step(0.1 * i, OdoPose(0.0, 0.0), 0.0, 3.0, lane, view, two_lane=False)[2]
        assert state == "junction-left"
        x, y = b._arc_end + np.array([-0.5, 0.0])  # just past the arc, heading west along the exit road
        return b.step(1.0, OdoPose(float(x), float(y), math.pi), 10.0, 3.0, exit_lane, None, two_lane=False)[2]

    assert turned(lane) == "cruise"
    assert turned(lost) == "junction-left"  # nothing to hand over to: the tail leads on


def _straight_lane(width: float = 4.0, heading: float = 0.0) -> LaneEstimate:
    ys = np.arange(3.5, 12.0, 0.5)
    return LaneEstimate("test", True, heading=heading, lane_width_m=width,
                        path_m=_rotate(np.column_stack([np.zeros_like(ys), ys]), heading))


def test_a_junction_met_askew_is_measured_along_the_road():
    # Out of a bend the car meets a junction askew (via_town's curved street: 20 degrees): the
    # side road's edges it sees at 3 m to its right lie further ahead of it than along the road,
    # and a right turn planned from them started late and left the road. A kerbed road runs
    # north along x = 0; its side road to the right spans y 18-22; the car, on the road's middle
    # at y = 12, points 0.25 rad right of the road.
    theta, x_m = 0.25, 3.0
    pose = OdoPose(0.0, 12.0, math.pi / 2 - theta)
    fy, ry = math.sin(pose.heading), -math.cos(pose.heading)
    near, far = ((edge - pose.y - x_m * ry) / fy for edge in (18.0, 22.0))  # where x_m crosses each edge
    assert (near + far) / 2 - 20.0 + 12.0 > 0.9  # askew, its middle looks 1 m further on than it is
    b = Behaviour()
    for i in range(3):  # a lone opening with the road ending ahead: a forced right
        view = JunctionView(None, Opening(near, far, True, dead=False, x_m=x_m), False, straight_dead=True)
        state = b.step(0.1 * i, pose, 0.0, 3.0, _straight_lane(heading=theta), view, two_lane=False)[2]
    assert state == "junction-right"
    tail = b.path[-20:]  # the straight run out of the arc, odometry frame
    assert np.all(tail[:, 0] > 4.0) and np.abs(tail[:, 1] - 20.0).max() < 0.15  # along the side road's middle
    assert b.decisions[-1]["near_m"] == pytest.approx(near, abs=0.1)  # when to plan: judged on what the car sees


def test_a_turn_sign_standing_past_a_crossing_driven_straight_over_is_for_the_next_junction():
    # Two junctions a few metres apart (via_town): the second's `left` sign stands 3.3 m past the
    # first's far side, and the car sees it last before the first. Passing a junction retires the
    # turn signs seen before it (they were for it), so the second was planned with no sign.
    b = Behaviour()
    b.observe_signs([("left", np.array([-3.0, 17.3]))])  # beyond the first's far side (14 m) and its slack
    for i in range(45):
        y = 0.5 * i
        if y < 14.0:  # a crossroads at 10-14 m, no sign of its own: straight on
            view = JunctionView(Opening(10.0 - y, 14.0 - y, True, dead=False),
                                Opening(10.0 - y, 14.0 - y, True, dead=False), True, straight_dead=False)
        else:  # a side road to the left at 22-26 m
            view = JunctionView(Opening(22.0 - y, 26.0 - y, True, dead=False), None, True, straight_dead=False)
        b.step(0.1 * i, OdoPose(0.0, y), y, 3.0, _straight_lane(), view, two_lane=False)
    assert [(d["sign"], d["turn"]) for d in b.decisions] == [(None, "straight"), ("left", "left")]


def test_a_bends_look_of_a_road_ending_does_not_make_the_next_junctions_road_on_a_dead_end():
    # Out of a left bend (via_town's top-right corner) the junction view read a lone left opening
    # with the road ending ahead, three frames running: the bend itself. Those verdicts outvoted
    # the crossing just past it, whose road goes on, and the car was sent into its dead-end stub.
    ys = np.arange(3.5, 12.0, 0.5)
    bending = LaneEstimate("test", True, curvature=-1 / 13, lane_width_m=4.0,
                           path_m=np.column_stack([-ys ** 2 / 26.0, ys]))
    b = Behaviour()
    for i in range(3):
        view = JunctionView(Opening(12.0, 15.0, True, dead=None), None, False, straight_dead=True)
        b.step(0.1 * i, OdoPose(0.0, 0.2 * i), 0.2 * i, 3.0, bending, view, two_lane=False)
    crossing = JunctionView(None, Opening(4.0, 8.0, True, dead=None), True, straight_dead=False)
    b.step(1.0, OdoPose(0.0, 3.0), 3.0, 3.0, _straight_lane(), crossing, two_lane=False)
    assert b.decisions and b.decisions[-1]["exits"] == ["right", "straight"]


def _junction_centre_ahead(route: Route, leg) -> float:
    """Arc length from a junction leg's start to the junction's centre (its pivot cell)."""
    centre = route.track.cell_centre((leg.tile.col, leg.tile.row))
    return float(route.project(*centre, s_hint=leg.s0 + 10.0)[0] - leg.s0)


@pytest.fixture(scope="module")
def painted_junctions():
    """(image, truth junction, side road centre ahead) 9 m before the box of each of the first
    junctions of a painted procedural track (a T-junction's through arms are plain road), seen by
    VIA's camera (the driver's default), and a plain frame."""
    track = Track.from_via(generate_map(0, size="medium"), style=RoadStyle())
    route = Route.drive(track, 1500, random_policy(np.random.default_rng(1)))
    renderer = Renderer(build_scene(track, seed=0))
    cam = via_camera(320, 240)
    out = []
    for leg in [l for l in route.legs if l.tile.junction][:5]:
        centre = _junction_centre_ahead(route, leg)
        box = leg.s0 + centre - track.cell_m / 2
        s = renderer.render_on_route(route, box - 9.0, cam, 0.0, 0.0, Effects.clean(), np.random.default_rng(0))
        out.append((s.image, s.truth.junction, 9.0 + track.cell_m / 2))
    plain = renderer.render_on_route(route, route.legs[0].s0 + 2.0, cam, 0.0, 0.0, Effects.clean())
    return cam, out, plain.image


def test_painted_junction_detector_sees_the_exits(painted_junctions):
    cam, frames, plain = painted_junctions
    det = JunctionDetector(cam)
    for image, truth, centre in frames:
        view = det.detect(image)
        exits = {s for s, o in (("left", view.left), ("right", view.right)) if o is not None}
        assert exits == set(truth.exits) - {"straight"}
        assert view.straight == ("straight" in truth.exits)
        side = view.right or view.left
        # the side road's centre, within a quarter of its width (VIA's camera sees the strips
        # beside a two-lane road only from about 10 m, which moves a near opening's middle)
        assert abs(side.centre_m - centre) < 1.9
    view = det.detect(plain)
    assert view.left is None and view.right is None


def test_junction_detector_judges_nothing_where_all_ground_looks_like_road(painted_junctions):
    """Dark grass the colour of asphalt: every side looks open, so no opening may be reported, and
    one frame where the verge happens to look different must not open one either (the far
    ground's share of road is remembered across frames)."""
    cam, frames, plain = painted_junctions
    image = frames[0][0]
    assert JunctionDetector(cam).detect(image).right is not None  # a real side road, fresh detector
    det = JunctionDetector(cam)
    view = det.detect(np.full_like(plain, 90))
    assert view.left is None and view.right is None and det.outer_share > 0.95
    assert det.outer_road_share(det.road_mask(image)) < 0.5
    view = det.detect(image)
    assert view.left is None and view.right is None


def kerbed_views(seed: int, backs=(12.0, 9.0, 6.0)):
    """For the first junctions of a VIA-style procedural track: (truth, [views from the road
    edges at each distance before it]); and the views 2 m into stretches of plain road."""
    track = Track.from_via(generate_map(seed))
    route = Route.drive(track, 1500, random_policy(np.random.default_rng(seed)))
    renderer = Renderer(build_scene(track, seed=seed))
    cam = via_camera(320, 240)
    method = lanes.get("road-edges", camera=cam)
    out = []
    for leg in [leg for leg in route.legs if leg.tile.junction][:3]:
        views = []
        for back in backs:
            method.reset()
            s = renderer.render_on_route(route, leg.s0 - back, cam)
            method(s.image)
            views.append(view_from_scan(method.state.scan))
        out.append((s.truth.junction, views))
    legs = route.legs
    plain = []
    for a in [a for a in range(len(legs) - 5) if all(legs[a + k].tile.tile_id == 0 for k in range(6))][:4]:
        method.reset()
        method(renderer.render_on_route(route, legs[a].s0 + 2.0, cam).image)
        plain.append(view_from_scan(method.state.scan))
    return out, plain


@pytest.mark.parametrize("seed", [1, 2, 6])
def test_kerbed_junctions_are_read_from_the_road_edges(seed):
    """On VIA's kerbed carriageway the openings are where an edge jumps away: the exits seen 6 m
    before a junction are the real ones (a dead-end arm is judged dead from further off, or not
    offered), straight on is told right, and plain road opens nothing."""
    junctions, plain = kerbed_views(seed)
    for truth, views in junctions:
        def reads(v):  # the turns it offers are the real ones, and straight on is right
            seen = {name for name, o in (("left", v.left), ("right", v.right)) if o is not None and o.closed}
            return set(truth.exits) - {"straight"} <= seen and v.straight == ("straight" in truth.exits)
        assert any(reads(v) for v in views)  # by the time the driver plans (12 m or closer)
        dead = {name for v in views for name, o in (("left", v.left), ("right", v.right))
                if o is not None and o.closed and o.dead}
        assert not dead & set(truth.exits)  # never a real exit judged a dead end
    assert all(v.left is None and v.right is None for v in plain)


def test_a_dead_end_arm_is_judged_dead_from_the_approach():
    """VIA's editor makes T-junctions whose arm leads nowhere: seen from 9-12 m, the arm's end
    is in view and the driver's memory keeps that verdict to the junction."""
    data = {"map_name": "stub", "map_size": {"x": 5, "y": 14}, "car_pos": {"x": 2, "y": 2},
            "cell_datas": [{"id_inmap": r * 5 + 2, "tile_id": 0, "rot": 0} for r in range(1, 11)]
            + [{"id_inmap": 12 * 5 + 2, "tile_id": 4, "rot": 0}]}  # a T at row 12, its branch east
    track = Track.from_via(data)  # the road's south end, and the T's north arm and branch, end
    assert len(track.dead_ends) == 3
    route = Route.drive(track, 60)
    renderer = Renderer(build_scene(track))
    cam = via_camera(320, 240)
    method = lanes.get("road-edges", camera=cam)
    verdicts = []
    for back in np.arange(14.0, 5.0, -1.0):
        s = renderer.render_on_route(route, route.legs[-1].s0 - back, cam)
        method(s.image)
        v = view_from_scan(method.state.scan)
        if v.right is not None and v.right.closed:
            verdicts.append(v.right.dead)
    assert True in verdicts and False not in verdicts


def test_a_short_arm_of_a_t_reached_along_its_stem_is_judged_dead_and_the_long_one_not():
    """A T-junction reached along its stem: its east arm ends one cell past the junction, its
    west arm goes on out of view. The barriers beside the stem hide the near part of both arms;
    the far rows see the east arm's end with grass beyond it."""
    w = 15
    cells = [{"id_inmap": r * w + 7, "tile_id": 0, "rot": 0} for r in range(1, 10)]
    cells.append({"id_inmap": 11 * w + 7, "tile_id": 4, "rot": 270})  # through road east-west, stem south
    cells += [{"id_inmap": 11 * w + c, "tile_id": 0, "rot": 90} for c in (9, 5, 4, 3, 2, 1)]
    track = Track.from_via({"map_name": "stem", "map_size": {"x": w, "y": 16}, "car_pos": {"x": 7, "y": 2},
                            "cell_datas": cells})
    assert len(track.dead_ends) == 3
    route = Route.drive(track, 60)
    renderer = Renderer(build_scene(track))
    cam = via_camera(320, 240)
    method = lanes.get("road-edges", camera=cam)
    verdicts = {"left": [], "right": []}
    tee = next(leg for leg in route.legs if leg.tile.junction)
    for back in np.arange(20.0, 5.0, -1.0):
        s = renderer.render_on_route(route, tee.s0 - back, cam)
        method(s.image)
        v = view_from_scan(method.state.scan)
        for side, o in (("left", v.left), ("right", v.right)):
            if o is not None and o.closed:
                verdicts[side].append(o.dead)
    assert verdicts["right"].count(True) >= 2 and False not in verdicts["right"]
    assert True not in verdicts["left"]


@pytest.mark.parametrize("style", ["via", "painted"])
def test_a_lockstep_drive_completes_a_lap_of_a_small_procedural_track(style):
    sim = Simulator(load_track("random", style, 3, size="small"), SimConfig(width=320, height=240, max_seconds=150))
    with Driver(Config.load(None, ["signs.enabled=false"])) as driver:
        rep = run_inprocess(sim, driver)
    assert rep["laps"] == 1 and rep["offroad_events"] == 0
    assert rep["cte_mean"] < 0.1


def test_a_stop_sign_makes_the_car_stop_and_hold():
    track = track_with_stop_sign(3, 30.0)
    # VIA's car takes about 12 s to reach the stop (half pedal, then coasting: no brakes), holds
    # 2.5 s and needs 3 s more to pass the sign, which is when the stop is judged
    sim = Simulator(track, SimConfig(max_seconds=24))
    speeds = []
    with Driver() as driver:
        rep = run_inprocess(sim, driver, lambda s, c, p: speeds.append((s.t, s.vehicle.speed, c.state)))
    stopped = [t for t, v, _ in speeds if v < 0.05 and t > 1.0]
    assert stopped and max(stopped) - min(stopped) >= 2.0  # a full stop, held 2 s
    assert rep["stops"] == {"required": 1, "complied": 1}
    assert speeds[-1][1] > 1.0  # and then it went on


def test_out_of_a_painted_turn_the_lane_takes_over_only_when_it_is_the_right_one():
    # Out of a painted right turn whose tail left the car on the centre line, the lane finder
    # latched the lane left of it (the wrong way's) and the car followed it. Past the arc the
    # lane leads on when it is the car's own or to its right; otherwise the tail does.
    ys = np.arange(3.5, 12.0, 0.5)
    lane = LaneEstimate("test", True, lane_width_m=3.2, path_m=np.column_stack([np.zeros_like(ys), ys]))

    def turned(offset, found=True):
        b = Behaviour()
        for i in range(3):  # a painted T reached along its stem: right and left open, no way on
            view = JunctionView(Opening(6.0, 13.0, True, dead=False), Opening(6.0, 13.0, True, dead=False), False,
                                straight_dead=True)
            state = b.step(0.1 * i, OdoPose(0.0, 0.0), 0.0, 3.0, lane, view, two_lane=True)[2]
        assert state == "junction-right"
        exit_lane = LaneEstimate("test", found, offset=offset, lane_width_m=3.2,
                                 path_m=lane.path_m if found else None)
        x, y = b._arc_end + np.array([0.5, 0.0])  # just past the arc, heading east along the exit road
        return b.step(1.0, OdoPose(float(x), float(y), 0.0), 10.0, 3.0, exit_lane, None, two_lane=True)[2]

    assert turned(-0.45) == "cruise"  # the lane found lies right of the car: the exit road's own
    assert turned(0.1) == "cruise"
    assert turned(0.45) == "junction-right"  # left of the car: the oncoming lane; the tail leads on
    assert turned(0.0, found=False) == "junction-right"


def test_a_straight_crossing_is_laid_along_the_road_remembered_not_the_last_frames_heading():
    # painted via_town's central crossroads: the lane's heading read at the junction's mouth
    # (-2.0 deg) was 4-5 degrees off what the approach had shown, and the straight path laid
    # along it took the car onto the exit road's edge line. The road's direction over the last
    # metres lays it.
    b = Behaviour()
    ys = np.arange(3.5, 12.0, 0.5)
    path = np.column_stack([np.zeros_like(ys), ys])
    for i in range(40):  # the approach: the car points 0.04 rad right of the road
        lane = LaneEstimate("test", True, heading=0.04, confidence=1.0, lane_width_m=3.2, path_m=path)
        b.step(0.1 * i, OdoPose(0.0, 0.2 * i), 0.2 * i, 3.0, lane, None, two_lane=True)
    misread = LaneEstimate("test", True, heading=-0.035, confidence=1.0, lane_width_m=3.2, path_m=path)
    crossing = JunctionView(Opening(6.0, 13.0, True, dead=False), Opening(6.0, 13.0, True, dead=False), True,
                            straight_dead=False)
    assert b.step(4.0, OdoPose(0.0, 8.0), 8.0, 3.0, misread, crossing, two_lane=True)[2] == "junction-straight"
    dx, dy = b.path[-1] - b.path[0]
    # the road points 0.04 rad left (counter-clockwise) of the car's north
    assert abs(math.atan2(dy, dx) - (math.pi / 2 + 0.04)) < 0.005


def test_past_a_painted_crossings_far_side_the_exit_roads_lane_takes_over_when_it_is_the_right_one():
    # a straight crossing laid a few degrees askew carried the car on to its path's end, 1.3 m
    # left of its lane (painted via_town, traced); past the crossing the exit road's lane leads on
    ys = np.arange(3.5, 12.0, 0.5)
    lane = LaneEstimate("test", True, confidence=1.0, lane_width_m=3.2,
                        path_m=np.column_stack([np.zeros_like(ys), ys]))

    def crossed(offset, y):
        b = Behaviour()
        crossing = JunctionView(Opening(6.0, 12.0, True, dead=False), Opening(6.0, 12.0, True, dead=False), True,
                                straight_dead=False)
        assert b.step(0.0, OdoPose(0.0, 0.0), 0.0, 3.0, lane, crossing, two_lane=True)[2] == "junction-straight"
        exit_lane = LaneEstimate("test", True, offset=offset, confidence=1.0, lane_width_m=3.2, path_m=lane.path_m)
        return b.step(1.0, OdoPose(0.0, y), y, 3.0, exit_lane, None, two_lane=True)[2]

    assert crossed(-0.35, 12.5) == "cruise"  # the lane lies right of the car: its own
    assert crossed(-0.35, 10.0) == "junction-straight"  # still inside the crossing
    assert crossed(0.45, 12.5) == "junction-straight"  # left of the car: maybe the oncoming lane


def test_pure_pursuit_shortens_its_lookahead_in_a_painted_bend():
    # The point ld ahead on a bend of radius R lies about ld^2 / 2R to its side: at 4.5 m/s the
    # painted lookahead (7.25 m) aims 1.5 m across an 18 m bend, and on seed 0's S-bend the car
    # ran 2 m inside it, off the road. With max_cut_m the lookahead keeps that aim within it.
    free = PurePursuit(lookahead_m=5.0, lookahead_per_mps=0.5)
    capped = PurePursuit(lookahead_m=5.0, lookahead_per_mps=0.5, max_cut_m=0.6)
    assert free.lookahead_m(4.5, 1 / 18) == pytest.approx(7.25)
    ld = capped.lookahead_m(4.5, 1 / 18)
    assert ld == pytest.approx(math.sqrt(2 * 0.6 * 18)) and ld ** 2 / (2 * 18) == pytest.approx(0.6)
    assert capped.lookahead_m(4.5, 0.0) == pytest.approx(7.25)  # straight: unchanged
    assert capped.lookahead_m(4.5, -1 / 4) == pytest.approx(3.0)  # never below min_lookahead_m
    # 3 m short of a right bend the capped car turns in later than the free one
    r, ys = 18.0, np.arange(0.5, 14.0, 0.25)
    x = np.where(ys < 3.0, 0.0, r - np.sqrt(r * r - np.clip(ys - 3.0, 0.0, None) ** 2))
    entry = LaneEstimate("test", True, curvature=1 / r, lane_width_m=3.2, path_m=np.column_stack([x, ys]))
    assert 0.0 < capped.step(entry, 4.5) < 0.5 * free.step(entry, 4.5)


def test_a_cut_opening_whose_far_side_no_earlier_frame_saw_is_not_a_side_road():
    # random looks, traced: road-coloured verge read as openings on the right, 15-20 m out on
    # some frames, and on one frame as a 1.6 m opening starting at the right strip's view edge
    # (cut); that frame's "side road" was taken for the right turn a sign asked for, 30 m before
    # its junction. A side road's far edge is a fixed place on the ground, seen frame after frame.
    lane = _straight_lane(3.2)

    def drive(params: BehaviourParams) -> list[str]:
        b, states = Behaviour(params), []
        views = [Opening(15.3, 20.7, True, dead=False), None, Opening(15.7, 20.3, True, dead=False),
                 Opening(7.6, 9.2, True, dead=False, cut=True),  # this frame's far side: not where any was
                 Opening(7.6, 8.9, True, dead=False, cut=True)]  # the next frame's: 0.3 m nearer, as driven
        for i, o in enumerate(views):
            view = JunctionView(None, o, True, straight_dead=False)
            states.append(b.step(0.1 * i, OdoPose(0.0, 0.3 * i), 0.3 * i, 3.0, lane, view)[2])
        return states

    assert drive(BehaviourParams()) == ["cruise"] * 4 + ["junction-straight"]
    # without asking where its far side was seen, the one frame's verge is planned as a junction
    assert drive(BehaviourParams(cut_far_m=1e9))[3] == "junction-straight"


def test_a_painted_junction_is_planned_where_the_last_frames_saw_its_side_road():
    # random looks with a road model, painted seed 18, traced: a crossing's right arm seen at
    # 202.0-209.0 m of the odometer on the frames of the 4 m before the plan (far side 205.6-210.0),
    # read 202.0-205.6 on the frame that planned the forced right turn. Laid from that frame
    # alone, the turn's arc began 1.8 m early and cut the corner over the verge.
    lane = _straight_lane(3.2)
    far_ends = [209.0, 208.9, 206.0, 210.0, 209.9, 209.9]

    def arc_start(params: BehaviourParams) -> float:
        b = Behaviour(params)
        for i, far in enumerate(far_ends + [205.6]):
            odo = 186.6 + 0.6 * i
            o = Opening(202.0 - odo, far - odo, True, dead=False)
            b.step(0.1 * i, OdoPose(0.0, odo), odo, 4.0, lane, JunctionView(None, o, False, straight_dead=True))
        assert b.path is not None, "the forced right turn is planned on the last frame"
        turned = np.flatnonzero(b.path[:, 0] > 1e-3)
        return float(b.path[turned[0], 1])

    p = BehaviourParams()
    y_c = 0.5 * (202.0 + float(np.median(far_ends + [205.6])))  # 205.5
    assert arc_start(p) == pytest.approx(y_c - p.lane_width_m / 2 - p.right_radius_m, abs=0.3)
    # this frame's reading alone: the arc begins where a 3.6 m side road's middle would put it
    assert arc_start(BehaviourParams(steady_m=0.0)) == pytest.approx(
        203.8 - p.lane_width_m / 2 - p.right_radius_m, abs=0.3)


def test_a_dead_end_road_turns_where_a_recent_frame_saw_its_side_road():
    # random looks with a road model, dev seed 100, traced: a T reached along its stem, its right
    # arm seen on one frame 10 m out, then on no other; its left arm read as a cut opening once,
    # which no earlier frame saw. No plan was made and the car drove into the T's mouth.
    lane = _straight_lane(3.2)

    def drive(params: BehaviourParams) -> str:
        b, state = Behaviour(params), ""
        views = [JunctionView(None, Opening(10.1, 15.3, True, dead=False), False, straight_dead=True),
                 None, None, None,
                 JunctionView(Opening(9.8, 11.4, True, dead=False, cut=True), None, False, straight_dead=True)]
        for i, view in enumerate(views):
            state = b.step(0.1 * i, OdoPose(0.0, 0.6 * i), 0.6 * i, 3.0, lane, view)[2]
        return state

    assert drive(BehaviourParams()) == "junction-right"  # the right arm, 2.4 m nearer than when seen
    # this frame's view alone (its cut left arm dropped as unseen before): no junction
    assert drive(BehaviourParams(side_memory_m=0.0)) == "cruise"


def test_a_plan_made_again_is_laid_along_the_road_the_plan_it_replaces_was():
    # random looks, VIA style, seed 14, traced: a right turn planned at the start, its arm found
    # dead 2.6 m on; the left turn made again along that frame's lane, read 11.6 degrees askew,
    # swung the car right first and it left the road 1.9 m wide of the turn. No road direction is
    # gathered while a plan is driven, so the plan made again had only that frame's lane.
    b = Behaviour()
    road = _straight_lane(4.0)

    def view(right_dead: bool, n: float) -> JunctionView:
        return JunctionView(Opening(n, n + 4.6, True, dead=False), Opening(n, n + 4.6, True, dead=right_dead),
                            False, straight_dead=True)

    b.step(0.0, OdoPose(0.0, 0.0), 0.0, 2.0, road, view(False, 11.7), two_lane=False)
    assert b.turn == "right"
    for i in (1, 2, 3):  # the right arm seen dead from closer (dead on two frames: planned again), the lane misread
        y = 0.9 * i
        lane = road if i < 2 else _straight_lane(4.0, heading=-0.2)
        b.step(0.1 * i, OdoPose(0.0, y), y, 2.0, lane, view(True, 11.7 - y), two_lane=False)
    assert b.turn == "left"
    # the path's lead-in runs along the road (the odometry's +y), not 11.5 degrees right of it
    lead = b.path[(b.path[:, 1] > 4.0) & (b.path[:, 1] < 7.0)]
    assert len(lead) and np.abs(lead[:, 0] - lead[0, 0]).max() < 0.05


def test_a_lone_opening_the_painted_lane_bent_toward_lately_is_a_bend():
    # random looks, traced: a left bend's lane bent 0.044-0.055 1/m for a third of a second, then
    # read straight on the frames of the bend's mouth; the bend's inside, a lone opening with the
    # road ending ahead, was planned as a forced left turn there and the car left the road
    ys = np.arange(3.5, 12.0, 0.5)
    bending = LaneEstimate("test", True, curvature=-0.05, lane_width_m=3.2,
                           path_m=np.column_stack([-0.025 * ys ** 2, ys]))
    straight = _straight_lane(3.2)

    def drive(params: BehaviourParams, two_lane: bool = True) -> str:
        b = Behaviour(params)
        for i in range(8):  # 2.4 m of the bend's lane, 0.6 m of straight-read frames
            b.step(0.1 * i, OdoPose(0.0, 0.3 * i), 0.3 * i, 3.0, bending if i < 6 else straight, None, two_lane)
        state = ""
        for i in range(8, 11):
            n = 10.0 - 0.3 * (i - 8)
            view = JunctionView(Opening(n, n + 7.0, True, dead=False), None, False, straight_dead=True)
            state = b.step(0.1 * i, OdoPose(0.0, 0.3 * i), 0.3 * i, 3.0, straight, view, two_lane)[2]
        return state

    assert drive(BehaviourParams()) != "junction-left"
    assert drive(BehaviourParams(bend_memory_m=0.0)) == "junction-left"  # this frame's lane alone: a turn
    assert drive(BehaviourParams(), two_lane=False) == "junction-left"  # a kerbed corner is driven as a turn


def test_road_coloured_verge_apart_from_the_road_is_no_side_road():
    # random looks with a road model, traced: shadowed grass read as road in blobs out in the
    # right strip, the verge between them and the road's edge not, and planned as a side road
    # 20 m before the junction. A side road joins the road: its ground is road from the edge out.
    cam = via_camera(320, 240)
    det = JunctionDetector(cam)
    bev = det.bev
    w, h = bev.size
    col = lambda x: int(round((x - bev.x_range_m[0]) * det.p.px_per_m))  # noqa: E731
    row = lambda y: int(round((bev.y_range_m[1] - y) * det.p.px_per_m))  # noqa: E731

    def frame(patch_from_m: float) -> np.ndarray:
        img = np.zeros((h, w, 3), np.uint8)
        img[:] = (40, 90, 60)  # grass
        img[:, col(-5.3):col(2.1)] = (100, 100, 100)  # a 7.4 m road, the car in its right lane
        for x in (-4.8, 1.6):  # its solid edge lines ...
            img[:, col(x) - 1:col(x) + 1] = (230, 230, 230)
        img[row(17.0):row(10.0), col(1.0):col(2.2)] = (100, 100, 100)  # ... the right one worn away here
        img[row(17.0):row(10.0), col(patch_from_m):col(6.8)] = (100, 100, 100)  # road-coloured ground
        return bev.unwarp(img, 0)

    joined, apart = frame(2.1), frame(4.3)
    assert JunctionDetector(cam).detect(joined).right is not None  # a side road's mouth
    assert JunctionDetector(cam).detect(apart).right is None  # verge, with grass between it and the road
    loose = JunctionDetector(cam, JunctionParams(joined=False)).detect(apart).right
    assert loose is not None  # (the strip alone took it for a side road)


def test_a_painted_crossing_is_laid_along_a_noisy_road_heading_not_the_mouths_lane():
    # random looks, traced: the approach's lane headings spread 5.4 degrees about the road's
    # direction (over RoadHeading's 2 degrees, so it said nothing), and the frame of the plan read
    # 12.6 degrees; the straight path laid along it left the road. On a painted road the noisy
    # road's median lays it.
    def laid(params: BehaviourParams) -> float:
        b = Behaviour(params)
        ys = np.arange(3.5, 12.0, 0.5)
        path = np.column_stack([np.zeros_like(ys), ys])
        rng = np.random.default_rng(0)
        for i in range(40):  # the road 0.04 rad left of the car's north, read with 4 degrees of noise
            lane = LaneEstimate("test", True, heading=0.04 + float(rng.normal(0.0, math.radians(4.0))),
                                confidence=1.0, lane_width_m=3.2, path_m=path)
            b.step(0.1 * i, OdoPose(0.0, 0.2 * i), 0.2 * i, 3.0, lane, None, two_lane=True)
        assert b.road_heading.car_heading(8.0, math.pi / 2) is None  # too spread for the strict test
        misread = LaneEstimate("test", True, heading=0.22, confidence=1.0, lane_width_m=3.2, path_m=path)
        crossing = JunctionView(Opening(6.0, 13.0, True, dead=False), Opening(6.0, 13.0, True, dead=False), True,
                                straight_dead=False)
        assert b.step(4.0, OdoPose(0.0, 8.0), 8.0, 3.0, misread, crossing, two_lane=True)[2] == "junction-straight"
        dx, dy = b.path[-1] - b.path[0]
        return math.atan2(dy, dx) - math.pi / 2  # the path's direction, radians left of north

    assert abs(laid(BehaviourParams()) - 0.04) < math.radians(2.0)
    # (with only the strict test, the mouth's lane lays it: 0.22 rad off the car's north)
    assert abs(laid(BehaviourParams(painted_heading_spread=math.radians(2.0))) - 0.22) < 1e-6


def test_straight_past_a_lone_opening_hands_over_to_a_lane_that_bends_away_from_it():
    # held-out random looks, painted, seed 309: a left opening where the road bent right. The
    # crossing was planned straight while the lane still ran straight; its lane then bent right
    # for 5 m and the path laid straight left the road before its end. The lane takes over once
    # it has bent away for bend_away_m; bending towards the opening (its side road's lines), or
    # away for less than that, the path stays.
    ys = np.arange(3.5, 14.0, 0.5)
    p = BehaviourParams()

    def bent(k: float) -> LaneEstimate:
        return LaneEstimate("test", True, curvature=k, lane_width_m=3.2, path_m=np.column_stack([k * ys ** 2 / 2, ys]))

    for later, frames, handed_over in ((bent(1 / 40), 6, True), (bent(-1 / 40), 6, False),
                                       (_straight_lane(3.2), 6, False), (bent(1 / 40), 3, False)):
        b = Behaviour()
        for i in range(4):  # planned straight on from 9.5 m, the lane straight
            n = 11.0 - 0.5 * i
            view = JunctionView(Opening(n, n + 5.0, True, dead=False), None, True, straight_dead=False)
            b.step(0.1 * i, OdoPose(0.0, 0.5 * i), 0.5 * i, 3.0, _straight_lane(3.2), view)
        assert [d["turn"] for d in b.decisions] == ["straight"] and b.path is not None
        states = []
        for i in range(4, 4 + frames):  # 0.4 m a frame along the path, the opening still in view
            n = 11.0 - 2.0 - 0.4 * (i - 4)
            view = JunctionView(Opening(n, n + 5.0, True, dead=False), None, True, straight_dead=False)
            states.append(b.step(0.1 * i, OdoPose(0.0, 2.0 + 0.4 * (i - 4)), 2.0 + 0.4 * (i - 4), 3.0, later, view)[2])
        assert (b.path is None) == handed_over, states
        assert len(b.decisions) == 1  # not planned again while the opening is passed
        if handed_over:
            first = states.index("cruise")  # handed over on the first frame bend_away_m past the first bent one
            assert 0.4 * (first - 1) < p.bend_away_m <= 0.4 * first
