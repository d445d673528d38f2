"""A road model's road checked against the world's colours (signlane.lanes.road_colour): verge the
model took for road is dropped where its colour is the verge's, shaded road and paint are kept,
and where road and verge share a colour the model's mask is left as it is. Then the painted
junction detector with it: a side road's near end where the side road begins, not 4 m early
over road-coloured-looking verge."""
import cv2
import numpy as np
import pytest

from signlane.camera import via_camera
from signlane.junction import JunctionDetector, JunctionParams
from signlane.lanes.road_colour import RoadColourParams, RoadColours, check_road_colour
from signlane.lanes.road_edges import RoadEdgesParams, RoadEdgesState, carriageway, road_edges_bev
from signlane.lanes.seg_model import FrameMaps

GREY, GREEN = (118, 122, 120), (100, 122, 103)  # BGR asphalt and a verge only a little greener (as traced)


def _ground(verge=GREEN, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A 120 x 110 bird's-eye view: a road 40 px wide up the middle on verge, textured, with a
    shadow across both; and where the road truly is (bool)."""
    rng = np.random.default_rng(seed)
    img = np.empty((110, 120, 3), np.uint8)
    img[:] = verge
    road = np.zeros((110, 120), bool)
    road[:, 40:80] = True
    img[road] = GREY
    img = np.clip(img.astype(int) + rng.integers(-12, 13, (110, 120, 1)), 0, 255)
    img[60:75] = img[60:75] * 0.45  # a tree's shadow over road and verge
    return img.astype(np.uint8), road


def _ahead() -> np.ndarray:
    a = np.zeros((110, 120), bool)
    a[80:, 52:68] = True
    return a


def test_verge_the_model_took_for_road_is_dropped_and_the_road_kept():
    img, road = _ground()
    model = road.copy()
    model[30:110, 80:100] = True  # 4 m of verge beside the road read as road
    seen = np.ones_like(road)
    out, colours = check_road_colour(model, img, _ahead(), seen, RoadColours(), RoadColourParams())
    verge_read = model & ~road
    assert (out & verge_read).sum() / verge_read.sum() < 0.05
    assert (out & road).sum() / road.sum() > 0.98  # the shadowed road too
    shadowed_road = road.copy()
    shadowed_road[:60] = shadowed_road[75:] = False
    assert (out & shadowed_road).sum() / shadowed_road.sum() > 0.98
    # the colours are remembered: a frame whose model sees no verge at all is still checked
    again = check_road_colour(model, img, _ahead(), model, colours, RoadColourParams())[0]
    assert (again & verge_read).sum() / verge_read.sum() < 0.05


def test_where_road_and_verge_share_a_colour_the_model_decides_alone():
    img, road = _ground(verge=(120, 121, 119))  # a grey verge
    model = road.copy()
    model[30:110, 80:100] = True
    out, colours = check_road_colour(model, img, _ahead(), np.ones_like(road), RoadColours(), RoadColourParams())
    assert colours.road is not None and colours.verge is not None  # both seen, too alike to tell apart
    assert np.array_equal(out, model)


def test_paint_is_kept_whatever_its_colour_and_a_colour_needs_enough_pixels():
    img, road = _ground()
    model = road.copy()
    model[:, 80:100] = True
    keep = np.zeros_like(road)
    keep[:, 84:86] = True  # an edge line the model marked as paint
    out = check_road_colour(model, img, _ahead(), np.ones_like(road), RoadColours(), RoadColourParams(), keep)[0]
    assert out[keep].all() and not out[:, 90:100].any()
    # too few pixels to learn a colour from: nothing is checked
    out, colours = check_road_colour(model, img, _ahead(), np.ones_like(road), RoadColours(),
                                     RoadColourParams(min_pixels=10**6))
    assert colours == RoadColours() and np.array_equal(out, model)


def _scene(bev, lane_width: float, side_from: float, side_to: float, verge_from: float):
    """A camera frame (bev.camera's) of a straight two-lane road, the car in its right lane, no
    right edge line, with a side road on the right from side_from to side_to metres ahead; and a
    road model's maps of it that also call the verge road from verge_from to side_from, 4.5 m
    out beside the road."""
    w, h = bev.size
    (x0, x1), (y0, y1) = bev.x_range_m, bev.y_range_m
    x, y = np.meshgrid(x0 + (np.arange(w) + 0.5) * (x1 - x0) / w, y1 - (np.arange(h) + 0.5) * (y1 - y0) / h)
    on_road = (x > -1.5 * lane_width) & (x < 0.5 * lane_width)
    truth = on_road | ((x >= 0.5 * lane_width) & (y > side_from) & (y < side_to))
    ground = np.empty((h, w, 3), np.uint8)
    ground[:] = GREEN
    ground[truth] = GREY
    ground[(np.abs(x + 1.5 * lane_width) < 0.08)] = (235, 235, 235)  # the left edge line
    texture = np.random.default_rng(1).integers(-10, 11, (h, w, 1))
    ground = np.clip(ground.astype(int) + texture, 0, 255).astype(np.uint8)
    cam = bev.camera
    image = cv2.warpPerspective(ground, bev.bev_to_image_h(), (cam.width, cam.height), flags=cv2.INTER_LINEAR)
    image[:cam.height // 2 - 10] = (230, 200, 160)  # sky
    road_read = truth | ((x >= 0.5 * lane_width) & (x < 0.5 * lane_width + 4.5) & (y > verge_from) & (y <= side_from))
    prob = cv2.warpPerspective(road_read.astype(np.float32), bev.bev_to_image_h(), (cam.width, cam.height),
                               flags=cv2.INTER_NEAREST)
    return image, FrameMaps(np.zeros_like(prob), prob, np.eye(3))


@pytest.mark.parametrize("check, near", [(True, 16.0), (False, 12.0)])
def test_a_painted_side_road_begins_where_its_asphalt_does(check, near):
    # random looks with a road model, painted seed 18, traced: the grass before a crossing's right
    # arm read as road 4 m deep, the arm planned 4 m early and the turn taken over the grass
    params = JunctionParams() if check else JunctionParams(colour=RoadColourParams(min_separation=1e9))
    det = JunctionDetector(via_camera(320, 240), params)
    image, maps = _scene(det.bev, det.p.lane_width_m, 16.0, 23.0, 12.0)
    view = det.detect(image, None, maps)
    assert view.right is not None
    assert view.right.near_m == pytest.approx(near, abs=0.6)


def test_the_carriageway_from_a_road_model_ends_where_its_asphalt_does():
    # random looks with a road model, painted seed 4, traced: a tree's shadow on the sand verge
    # read as road beside the road, the carriageway misread, and the painted lane refused for
    # not lying in its right half
    def carriageway_of(p: RoadEdgesParams):
        cam = via_camera(320, 240)
        image, maps = _scene(road_edges_bev(cam, p, RoadEdgesState()), 3.2, 40.0, 50.0, 0.0)  # verge read all along
        state = RoadEdgesState()
        for _ in range(3):
            state = carriageway(image, cam, p, state, maps)[3]
        return state.width_m, float(np.median(state.scan.edge_l)), float(np.median(state.scan.edge_r))

    width, left, right = carriageway_of(RoadEdgesParams())
    assert (width, left, right) == pytest.approx((6.4, -4.8, 1.6), abs=0.3)
    width, left, right = carriageway_of(RoadEdgesParams(colour=RoadColourParams(min_separation=1e9)))
    assert abs(right - 1.6) > 0.4 and abs(width - 6.4) > 2.0  # without the colours: not the road
