"""On a two-lane road the car keeps to the right lane when the look hides the road's paint:
a road that has shown its centre line stays a two-lane road while it stays two lanes wide
(road_edges: RoadEdgesState.held), a paint lane left of the carriageway's middle is the
oncoming lane, not the car's, and one centred beyond the right lane is the verge (auto:
_keeps_right). Traced on random looks, where a worn centre line made the car steer to the
carriageway's middle, a worn right edge line let the paint method take the far edge line and the
centre line for the car's lane lines, and out of bends it took the right edge line for the
lane's left line and put the lane on the grass."""
from dataclasses import replace

import numpy as np

from signlane.camera import Camera
from signlane.lanes.auto import AutoParams, _keeps_right
from signlane.lanes.road_edges import RoadEdgesParams, RoadEdgesState, carriageway, road_edges_bev
from signlane.types import LaneEstimate

P = RoadEdgesParams()
CAM = Camera().with_size(320, 240)


def _frame(left_m: float, right_m: float, centre_m: float | None, phase_m: float = 0.0) -> np.ndarray:
    """A camera frame of a straight grey road between ground x = left_m and right_m (metres, +
    right of the car) on brown verge, with a dashed white centre line at centre_m (3 m dashes,
    4 m gaps, shifted by phase_m as the car drives on) or none."""
    bev = road_edges_bev(CAM, P, RoadEdgesState())
    w, h = bev.size
    img = np.zeros((h, w, 3), np.uint8)
    img[:] = (60, 110, 150)
    col = lambda x: int(round((x - bev.x_range_m[0]) * P.px_per_m))  # noqa: E731
    img[:, col(left_m):col(right_m)] = (110, 110, 110)
    if centre_m is not None:
        for v in range(h):
            y = bev.y_range_m[1] - (v + 0.5) / P.px_per_m + phase_m
            if y % 7.0 < 3.0:
                img[v, col(centre_m) - 1:col(centre_m) + 1] = (235, 235, 235)
    return bev.unwarp(img, 0)


def _drive(frames, state=None, params=P):
    state = state or RoadEdgesState()
    kinds = []
    for img in frames:
        *_, state, _ = carriageway(img, CAM, params, state)
        kinds.append(state.two_lane)
    return kinds, state


# a painted two-lane road 7.4 m wide, the car in the middle of its right lane
PAINTED = dict(left_m=-5.3, right_m=2.1)


def test_a_two_lane_road_whose_centre_line_fades_stays_two_lane_while_it_is_two_lanes_wide():
    seen, state = _drive([_frame(**PAINTED, centre_m=-1.6, phase_m=0.2 * i) for i in range(20)])
    assert seen[-1] and state.held
    faded = [_frame(**PAINTED, centre_m=None) for _ in range(40)]
    kinds, faded_state = _drive(faded, state)
    assert all(kinds)
    # without the hold the road turns kerbed within a second (the car would steer to its middle)
    kinds, _ = _drive(faded, replace(state, held=False), replace(P, two_lanes_m=99.0))
    assert not kinds[-1]
    # a few frames that measure the faded road narrow (a kerbed carriageway's 4 m) do not end the
    # hold (one such frame did, before RoadEdgesParams.release_frames)
    narrow = [_frame(-2.0, 2.0, None) for _ in range(3)]
    kinds, held = _drive(narrow + faded, faded_state)
    assert all(kinds) and held.held
    kinds, _ = _drive(narrow + faded, faded_state, replace(P, release_frames=1))
    assert not kinds[-1]
    # a road narrowed to a kerbed carriageway's 4 m without a centre line is kerbed again
    kinds, state = _drive([_frame(-2.0, 2.0, None) for _ in range(40)], state)
    assert not kinds[-1] and not state.held


def test_a_wide_road_never_seen_with_a_centre_line_is_not_held_two_lane():
    kinds, state = _drive([_frame(**PAINTED, centre_m=None) for _ in range(30)])
    assert not any(kinds) and not state.held


def _lane_at(centre_x: float) -> LaneEstimate:
    ys = np.arange(2.0, 12.0, 0.5)
    return LaneEstimate("test", True, offset=-centre_x / 3.2, lane_width_m=3.2,
                        path_m=np.column_stack([np.full_like(ys, centre_x), ys]))


def test_the_paint_lane_is_the_cars_only_in_the_right_half_of_the_carriageway():
    params = AutoParams()
    for car_m in (0.0, 0.8, -0.8):  # the car in its lane's middle, or 0.8 m left or right of it
        _, state = _drive([_frame(PAINTED["left_m"] - car_m, PAINTED["right_m"] - car_m, -1.6 - car_m, 0.2 * i)
                           for i in range(5)])
        scan = state.scan
        assert _keeps_right(_lane_at(-car_m), scan, params)  # the right lane: its centre 1.6 m right of the middle
        assert not _keeps_right(_lane_at(-car_m - 3.2), scan, params)  # the oncoming lane
        assert not _keeps_right(_lane_at(-car_m - 1.6), scan, params)  # a "lane" astride the centre line
        # the verge beyond the right edge line, taken for a lane whose left line is the edge line
        # (traced out of a bend on random looks: the car ran along the edge line on the grass)
        assert not _keeps_right(_lane_at(-car_m + 3.2), scan, params)
        # a lane centred 3.1 m right of the middle (share 0.42), still inside the right edge
        assert not _keeps_right(_lane_at(-car_m + 1.5), scan, params)
        assert _keeps_right(_lane_at(-car_m + 1.5), scan, replace(params, keep_inside_share=1.0))
        assert _keeps_right(_lane_at(-car_m + 0.6), scan, params)  # the right lane, read 0.6 m off
        # where the carriageway was not seen, it cannot tell: the paint stands
        assert _keeps_right(_lane_at(-car_m - 3.2), None, params)


def test_a_carriageway_narrower_than_two_lanes_has_no_centre_line():
    # random looks, traced: VIA's kerbed road (4.2-4.8 m measured) with grey kerbs turned
    # "two-lane" in a bend, where the carriageway's middle band ran over a kerb, and the paint
    # method steered the car onto it. A stripe down a 4 m carriageway's middle stands in here.
    narrow = [_frame(-2.0, 2.0, centre_m=0.0, phase_m=0.2 * i) for i in range(30)]
    kinds, state = _drive(narrow)
    assert not any(kinds) and state.centre_paint < 0.01
    kinds, _ = _drive(narrow, params=replace(P, centre_line_from_m=0.0))
    assert kinds[-1]  # (a centre line when any width may have one)


def test_a_paint_lane_centred_beyond_the_right_edge_is_the_verge_where_the_left_edge_is_out_of_view():
    # the road's left edge comes into the near view only 9 m ahead (traced out of bends on random
    # looks: the car near the right edge line, the paint lane on the grass beyond it): the width's
    # share cannot tell, the right edge (1.8 m right of the car) can
    _, state = _drive([_frame(-9.0, 1.8, None, 0.2 * i) for i in range(5)])
    scan, params = state.scan, AutoParams()
    both = np.flatnonzero(scan.ok_l & scan.ok_r)
    assert scan.y[both[0]] > 8.5  # no near row with both edges seen
    assert _keeps_right(_lane_at(0.0), scan, params) and _keeps_right(_lane_at(1.0), scan, params)
    assert not _keeps_right(_lane_at(2.5), scan, params)  # centred 0.7 m past the edge
    assert not _keeps_right(_lane_at(3.4), scan, params)  # the edge line taken for its left line
    # the right edge needs min_rows rows seen to tell
    assert _keeps_right(_lane_at(3.4), scan, replace(params, road=replace(params.road, min_rows=1000)))
