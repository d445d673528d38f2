"""Renderer: determinism by seed and ground truth that agrees with the pixels, on both road
styles: painted lanes (the paint, its boundaries, offsets, curvature) and VIA's kerbed
carriageway (no paint, the drivable surface between the kerbs, white kerbs, green barriers
that are not road, signs lit brighter than the scene)."""
import math

import numpy as np
import pytest

from lane_helpers import stadium
from signlane.camera import Camera, via_camera
from signlane.world.effects import Effects
from signlane.world.maps import bundled_map
from signlane.world.render import Renderer
from signlane.world.route import Route
from signlane.world.sampling import FrameSampler, SamplerConfig
from signlane.world.scene import build_scene
from signlane.world.track import RoadStyle, Track, WorldObject

# a ring of four 2x2 quarter turns filling a 4x4 grid, entered northbound on its east side
RING = {"map_name": "ring", "map_size": {"x": 4, "y": 4}, "car_pos": {"x": 3, "y": 1},
        "cell_datas": [{"id_inmap": 15, "tile_id": 2, "rot": 0}, {"id_inmap": 12, "tile_id": 2, "rot": 90},
                       {"id_inmap": 0, "tile_id": 2, "rot": 180}, {"id_inmap": 3, "tile_id": 2, "rot": 270}]}


@pytest.fixture(scope="module")
def loop():
    """The bundled loop (two T-junctions and a lane shift) in the painted two-lane style."""
    track = bundled_map("loop_demo", style="painted")
    return track, Route.loop(track), Renderer(build_scene(track, seed=3))


@pytest.fixture(scope="module")
def via_stadium():
    """A stadium in VIA's own style, seen by VIA's camera from the start of its 24 m west side."""
    track = Track.from_via(stadium())
    route = Route.loop(track)
    return track, route, Renderer(build_scene(track, seed=1)), via_camera(640, 480)


def test_same_seed_same_pixels_other_seed_other_pixels():
    for style in ("painted", "via"):
        cfg = SamplerConfig(effects="hard", style=style)
        a = FrameSampler(11, cfg).sample(7)
        b = FrameSampler(11, cfg).sample(7)
        c = FrameSampler(12, cfg).sample(7)
        assert np.array_equal(a.image, b.image) and np.array_equal(a.truth.marking_mask, b.truth.marking_mask)
        assert np.array_equal(a.truth.drivable_mask, b.truth.drivable_mask)
        assert a.truth.to_label() == b.truth.to_label()
        assert np.mean(np.abs(a.image.astype(int) - c.image.astype(int))) > 5


# --------------------------------------------------------------------------- painted lanes
def _row_agreement(mask: np.ndarray, line: np.ndarray, search: float = 6.0):
    """For each polyline point whose row has a run of paint within `search` px: |run centre - x|,
    using the whole run. Rows at the ends of dashes, runs cut by the frame and runs much shorter
    than the typical one are skipped: their centres are not the line's centre."""
    runs = []
    for x, y in line:
        row = int(round(y))
        if not 2 <= row < mask.shape[0] - 2:
            continue
        lo, hi = int(max(0, x - search)), int(x + search) + 1
        if not (mask[row - 2, lo:hi].any() and mask[row + 2, lo:hi].any()):
            continue  # the end of a dash: its rows are cut on a slant
        on = np.concatenate([[0], (mask[row] > 0).astype(np.int8), [0]])
        edges = np.diff(on)
        starts, ends = np.nonzero(edges == 1)[0], np.nonzero(edges == -1)[0] - 1
        if len(starts) == 0:
            continue
        gap = np.maximum(0, np.maximum(starts - x, x - ends))
        k = int(np.argmin(gap))
        if gap[k] <= search and starts[k] > 0 and ends[k] < mask.shape[1] - 1:  # cut runs: no centre
            runs.append((ends[k] - starts[k] + 1, abs((starts[k] + ends[k]) / 2 - x)))
    if not runs:
        return np.zeros(0)
    runs = np.array(runs)
    full = runs[:, 0] >= 0.8 * np.median(runs[:, 0])
    return runs[full, 1]


@pytest.mark.parametrize("seed", range(6))
def test_marking_pixels_and_projected_boundaries_agree_within_2px(seed):
    """Solid edge lines and dashes sit on the projected ego-lane boundaries."""
    sampler = FrameSampler(seed, SamplerConfig(effects="clean", randomise=False, width=640, height=480))
    checked = 0
    for i in range(0, 40, 5):
        t = sampler.sample(i).truth
        if t.junction is not None and t.junction.distance < 40:
            continue  # markings stop inside junctions (a T's block is three cells long)
        for line in (t.left, t.right):
            near = line[line[:, 1] > 0.6 * t.camera.height]  # lines are >= 3 px wide here
            if len(near) < 2:
                continue
            rows = np.arange(np.ceil(near[:, 1].min()), np.floor(near[:, 1].max()) + 1)
            dense = np.column_stack([np.interp(rows, near[::-1, 1], near[::-1, 0]), rows])
            errs = _row_agreement(t.marking_mask, dense)
            if len(errs) >= 20:
                assert errs.max() <= 2.0 and np.median(errs) < 1.0, (seed, i, errs.max())
                checked += 1
    assert checked >= 2  # the check must not pass vacuously


def _straight_s(route, ahead_m: float = 25.0) -> float:
    """The start of the first stretch of route with ahead_m of straight road."""
    for s in np.arange(2.0, route.length, 1.0):
        window = (route.s >= s - 3) & (route.s <= s + ahead_m)
        if np.all(np.abs(route.curvature[window]) < 1e-6):
            return float(s)
    raise AssertionError("no straight stretch")


@pytest.mark.parametrize("style", ["painted", "via"])
def test_offset_and_heading_signs_follow_the_pose(loop, style):
    if style == "painted":
        track, route, renderer = loop
        cam = Camera()
    else:
        track = bundled_map("loop_demo")
        route, renderer, cam = Route.loop(track), Renderer(build_scene(track, seed=3)), via_camera(320, 240)
    s = _straight_s(route)
    lw = track.style.lane_width
    right = renderer.render_on_route(route, s, cam, lateral_m=0.8).truth
    left = renderer.render_on_route(route, s, cam, lateral_m=-0.8).truth
    assert right.offset == pytest.approx(0.8 / lw, abs=0.01)
    assert left.offset == pytest.approx(-0.8 / lw, abs=0.01)
    assert right.lane_width_m == lw
    # when the car is right of centre, the lane centre appears left of the image centre
    assert right.center[0, 0] < cam.width / 2 < left.center[0, 0]
    turned = renderer.render_on_route(route, s, cam, heading_offset=math.radians(5)).truth
    assert turned.heading == pytest.approx(math.radians(5), abs=1e-3)
    # pointing right of the lane: the lane ahead (on the straight, 20 m on) drifts to the left
    row_20m = cam.ground_to_image(np.array([[0.0, 20.0]]))[0, 1]
    ahead = turned.center[turned.center[:, 1] >= row_20m]
    assert len(ahead) > 10 and ahead[-1, 0] < cam.width / 2 - 10


def test_curvature_sign_on_a_left_and_a_right_bend():
    # painted cells (12 m): true arcs of radius 1.5 cells
    track = Track.from_via(RING, style=RoadStyle())
    renderer = Renderer(build_scene(track))
    R = 1.5 * track.cell_m
    signs = []
    for reverse in (False, True):
        route = Route.loop(track, reverse=reverse)
        t = renderer.render_on_route(route, 5.0, Camera()).truth
        # the route's own turning direction decides the sign; |k| is 1/R
        expected = float(np.sign(np.median(route.curvature)))
        assert np.sign(t.curvature) == expected and abs(abs(t.curvature) - 1 / R) < 0.01
        # bending right: the far lane centre is right of the near one in the image
        assert np.sign(t.center[-1, 0] - t.center[0, 0]) == expected
        signs.append(expected)
    # northbound on the ring's east side is counter-clockwise: left (negative), reversed right
    assert signs == [-1.0, 1.0]
    # VIA's chamfered turns (R = 6 m) bend the same ways, about as much on average
    track = Track.from_via(RING)
    renderer = Renderer(build_scene(track))
    for reverse, sign in ((False, -1.0), (True, 1.0)):
        route = Route.loop(track, reverse=reverse)
        t = renderer.render_on_route(route, 5.0, via_camera(320, 240)).truth
        assert np.sign(t.curvature) == sign and abs(abs(t.curvature) - 1 / 6.0) < 0.04


def _sign_ahead(pose, kind="stop", ahead=12.0, beside=3.5, seed=1):
    f, r = pose.forward, pose.right
    p = np.array([pose.x, pose.y]) + ahead * f + beside * r
    return WorldObject(kind, float(p[0]), float(p[1]), pose.heading + math.pi, seed=seed)


def test_sign_box_contains_its_rendered_pixels(loop):
    track, route, _ = loop
    pose = route.pose_at(_straight_s(route))
    sign = _sign_ahead(pose)  # a stop sign 12 m ahead on the right, facing the car
    base = build_scene(track, seed=3)
    base.objects = []
    with_sign = build_scene(track, seed=3)
    with_sign.objects = [sign]
    cam = Camera(640, 480)
    a = Renderer(base).render(pose, cam, route=route).image
    smp = Renderer(with_sign).render(pose, cam, route=route)
    assert len(smp.truth.signs) == 1
    st = smp.truth.signs[0]
    assert st.label == "stop" and st.distance == pytest.approx(np.hypot(12.0, 3.5), abs=0.3)
    x, y, w, h = st.box
    assert w > 20 and h > 20
    changed = np.any(np.abs(smp.image.astype(int) - a.astype(int)) > 8, axis=2)
    ys, xs = np.nonzero(changed)
    face = ys < y + h  # the pole hangs below the face
    assert np.all((xs[face] >= x - 1) & (xs[face] <= x + w) & (ys[face] >= y - 1))
    # and the face fills its box: most of the box changed
    assert changed[y:y + h, x:x + w].mean() > 0.6


def test_occlusion_fraction_of_a_sign_behind_a_nearer_board(loop):
    track, route, _ = loop
    pose = route.pose_at(_straight_s(route))
    f, r = pose.forward, pose.right
    far = np.array([pose.x, pose.y]) + 15.0 * f + 3.0 * r
    near = np.array([pose.x, pose.y]) + 8.0 * f + 1.8 * r  # in front of the sign's left half
    scene = build_scene(track, seed=3)
    scene.objects = [WorldObject("left", *map(float, far), pose.heading + math.pi, seed=2),
                     WorldObject("blue_rect", *map(float, near), pose.heading + math.pi, size_m=0.6, seed=5)]
    t = Renderer(scene).render(pose, Camera(640, 480), route=route).truth
    assert len(t.signs) == 1 and 0.05 < t.signs[0].occluded < 0.95
    assert t.distractors and t.distractors[0][0] == "blue_rect"


def test_junction_ahead_is_reported_with_its_exits(loop):
    track, route, renderer = loop
    found = set()
    for s in np.arange(0, route.length, 10.0):
        j = renderer.render_on_route(route, float(s), Camera()).truth.junction
        if j is not None:
            assert j.distance >= 0 and j.chosen in j.exits
            found.add(j.exits)
    assert ("left", "straight") in found or ("right", "straight") in found
    # the distance counts down to each junction the lap passes, is 0 in the first half of the
    # way through its block (a T's is three cells long) and then goes to the next junction
    legs = route.legs
    junctions = [k for k, leg in enumerate(legs) if leg.tile.junction]
    assert len(junctions) >= 2
    for n, k in enumerate(junctions):
        leg = legs[k]
        length = (legs[k + 1].s0 if k + 1 < len(legs) else route.length) - leg.s0
        before = renderer.render_on_route(route, leg.s0 - 7.0, Camera()).truth.junction
        inside = renderer.render_on_route(route, leg.s0 + 0.4 * length, Camera()).truth.junction
        past = renderer.render_on_route(route, leg.s0 + 0.6 * length, Camera()).truth.junction
        assert before.distance == pytest.approx(7.0, abs=0.05) and inside.distance == 0.0
        assert before.chosen == inside.chosen == leg.turn
        following = legs[junctions[(n + 1) % len(junctions)]]
        ahead = (following.s0 - leg.s0 - 0.6 * length) % route.length
        assert past.distance == pytest.approx(ahead, abs=0.05) and past.chosen == following.turn


def test_a_dead_end_arm_is_not_an_exit():
    """A T-junction whose branch leads off the map: the car is offered only the way on."""
    data = stadium()
    w = data["map_size"]["x"]
    east = {r * w + w - 2 for r in (5, 6, 7)}  # three straights of the east side
    data["cell_datas"] = [c for c in data["cell_datas"] if c["id_inmap"] not in east]
    data["cell_datas"].append({"id_inmap": 6 * w + w - 2, "tile_id": 4, "rot": 0})  # branch east, off the map
    track = Track.from_via(data)
    assert len(track.dead_ends) == 1
    route = Route.loop(track)
    renderer = Renderer(build_scene(track, seed=0))
    leg, = [leg for leg in route.legs if leg.tile.junction]
    t = renderer.render_on_route(route, leg.s0 - 5.0, via_camera(320, 240)).truth
    assert t.junction.exits == ("straight",) and t.junction.chosen == "straight"
    assert t.junction.distance == pytest.approx(5.0, abs=0.05)


def test_effects_change_pixels_not_truth(loop):
    _, route, renderer = loop
    cam = Camera()
    clean = renderer.render_on_route(route, 50.0, cam, effects=Effects(noise=10, jpeg_prob=1.0),
                                     rng=np.random.default_rng(1))
    plain = renderer.render_on_route(route, 50.0, cam)
    assert not np.array_equal(clean.image, plain.image)
    assert np.array_equal(clean.truth.marking_mask, plain.truth.marking_mask)
    assert np.array_equal(clean.truth.drivable_mask, plain.truth.drivable_mask)
    assert clean.truth.to_label() == plain.truth.to_label()


# --------------------------------------------------------------------------- VIA's kerbed road
def test_via_frames_have_no_lane_paint_but_a_road():
    sampler = FrameSampler(3, SamplerConfig(effects="clean", randomise=False, style="via"))
    for i in range(0, 50, 10):
        t = sampler.sample(i).truth
        assert t.marking_mask.max() == 0
        assert t.drivable_mask.mean() > 0.05 * 255
        assert t.lane_width_m == 4.0 and t.camera.hfov_deg == pytest.approx(75.18, abs=0.01)


def _edge_columns(pose, cam, route, s, lateral_m, rows):
    """Image columns, at each of `rows`, of the line `lateral_m` right of the road's centre line
    over the next 20 m (VIA's road has one carriageway: its centre is the ego path)."""
    idx = route.ahead(s, 20.0)
    line = route.centre[idx] + lateral_m * route.right[idx]
    g = pose.to_ground(line)
    pix, depth = cam.project(np.column_stack([g, np.zeros(len(g))]))
    keep = depth > 0.5
    pix = pix[keep]
    order = np.argsort(pix[:, 1])
    return np.interp(rows, pix[order, 1], pix[order, 0], left=np.nan, right=np.nan)


def _near_rows(cam, lo_m=4.0, hi_m=12.0):
    """Image rows that see the ground from lo_m to hi_m ahead."""
    rows = np.arange(cam.height)
    ahead = np.array([cam.image_to_ground(np.array([[cam.width / 2, r + 0.5]]))[0, 1] for r in rows])
    return rows[(ahead >= lo_m) & (ahead <= hi_m)]


def test_via_drivable_mask_is_the_carriageway_between_the_kerbs_and_the_kerbs_are_white(via_stadium):
    track, route, renderer, cam = via_stadium
    s = route.start_s
    smp = renderer.render_on_route(route, s, cam)
    pose = smp.truth.pose
    drivable, img = smp.truth.drivable_mask > 0, smp.image.astype(int)
    hw, kerb = track.style.road_half_width, track.style.kerb_m
    assert (hw, kerb) == (2.0, 0.18)
    rows = _near_rows(cam)
    assert len(rows) > 60
    cols = {name: _edge_columns(pose, cam, route, s, lat, rows)
            for name, lat in (("left", -hw), ("right", hw), ("left_kerb", -hw - kerb), ("right_kerb", hw + kerb),
                              ("left_out", -hw - kerb - 1.5), ("right_out", hw + kerb + 1.5))}
    inside = outside = kerb_px = total_in = total_out = 0
    whites = []
    for i, r in enumerate(rows):
        xl, xr = cols["left"][i], cols["right"][i]
        a, b = int(math.ceil(xl + 2)), int(math.floor(xr - 2))
        inside += drivable[r, a:b + 1].sum()
        total_in += b - a + 1
        # beyond the kerbs (2 px clear of them), out to 1.5 m: not road
        beyond = ((cols["left_out"][i], cols["left_kerb"][i] - 2), (cols["right_kerb"][i] + 2, cols["right_out"][i]))
        for lo, hi in beyond:
            lo, hi = int(math.ceil(max(lo, 0))), int(math.floor(min(hi, cam.width - 1)))
            outside += drivable[r, lo:hi + 1].sum()
            total_out += max(hi - lo + 1, 0)
        # the kerbs: 0.18 m bands just outside the edges, not road, white
        for lo, hi in ((cols["left_kerb"][i] + 1.5, xl - 1.5), (xr + 1.5, cols["right_kerb"][i] - 1.5)):
            if hi - lo >= 1:
                seg = slice(int(math.ceil(lo)), int(math.floor(hi)) + 1)
                kerb_px += drivable[r, seg].sum()
                whites.append(img[r, seg])
    assert total_in > 10000 and inside == total_in  # every carriageway pixel is drivable
    assert total_out > 5000 and outside == 0  # nothing beyond the kerbs is
    whites = np.concatenate(whites)
    assert len(whites) > 300 and kerb_px == 0
    assert np.median(whites.min(axis=1)) > 200 and np.median(np.ptp(whites, axis=1)) < 12  # white


def test_via_barriers_are_green_and_not_drivable(via_stadium):
    track, route, renderer, cam = via_stadium
    assert renderer.scene.barriers is not None and len(renderer.scene.barriers.base) > 50
    smp = renderer.render_on_route(route, route.start_s, cam)
    b, g, r = (smp.image[..., k].astype(int) for k in range(3))
    green = (g > 150) & (r < 120) & (b < 120)  # the barrier's (60, 205, 60); grass is darker
    assert green.sum() > 500
    assert not (smp.truth.drivable_mask[green] > 0).any()
    # on both sides of the road, beyond the kerbs, and never between them
    rows = _near_rows(cam, 3.5, 20.0)
    left = _edge_columns(smp.truth.pose, cam, route, route.start_s, -2.18, rows)
    right = _edge_columns(smp.truth.pose, cam, route, route.start_s, 2.18, rows)
    cols = np.arange(cam.width)
    sides = np.zeros(3, int)
    for r, xl, xr in zip(rows, left, right):
        on = green[r]
        sides += [on[cols < xl].sum(), on[(cols >= xl) & (cols <= xr)].sum(), on[cols > xr].sum()]
    assert sides[0] > 500 and sides[2] > 500 and sides[1] == 0


def test_via_sign_faces_are_lit_brighter_than_in_a_painted_scene():
    faces = {}
    for style in ("via", "painted"):
        track = Track.from_via(stadium(), style=RoadStyle.named(style))
        route = Route.loop(track)
        scene = build_scene(track, seed=2)
        pose = route.pose_at(route.start_s)
        scene.objects = [_sign_ahead(pose, "left", ahead=10.0, beside=track.style.road_half_width + 2.0)]
        smp = Renderer(scene).render(pose, Camera(640, 480), route=route)
        st, = smp.truth.signs
        x, y, w, h = st.box
        faces[style] = (smp.image[y + h // 4:y + 3 * h // 4, x + w // 4:x + 3 * w // 4].astype(float),
                        scene.looks.sign_gain)
        assert st.label == "left" and w > 30
    (via, gain), (painted, one) = faces["via"], faces["painted"]
    assert one == 1.0 and gain > 1.1 and via.shape == painted.shape
    assert via.mean() > painted.mean() * 1.1
    # not saturated: each pixel is the painted one times the gain
    ok = (painted > 20) & (painted < 180)
    assert ok.sum() > 200 and np.median(via[ok] / painted[ok]) == pytest.approx(gain, abs=0.05)


def test_topdown_legend_is_a_strip_below_an_unchanged_map():
    from signlane.world.topdown import SIGN_BGR, draw_topdown
    track = bundled_map("via_town")
    scene = build_scene(track)
    lap = Route.loop(track).lane
    plain = draw_topdown(scene, path_xy=lap)
    with_legend = draw_topdown(scene, path_xy=lap, legend="lap from the start")
    h = plain.shape[0]
    assert with_legend.shape[0] > h + 15 and with_legend.shape[1] == plain.shape[1]
    assert np.array_equal(with_legend[:h], plain)  # the minimap part stays VIA's
    strip = with_legend[h:].reshape(-1, 3)
    for colour in [(0, 0, 255), (0, 255, 0), SIGN_BGR["stop"], SIGN_BGR["no_left"]]:  # path, start, signs
        assert (np.abs(strip.astype(int) - colour).sum(axis=1) < 40).sum() > 10


def test_where_the_car_left_the_road_is_in_the_report_and_crossed_on_the_picture():
    from signlane.sim.score import Score
    from signlane.world.topdown import MARK_BGR, draw_topdown, minimap_frame
    score = Score(lane_width_m=4.0, offroad_m=2.0)
    assert not score.frame(1.0, 1.9, 5.0, None, (3.0, 4.0))
    assert score.frame(2.0, -2.2, 5.0, None, (10.0, -6.0))
    assert score.offroad == [(2.0, 10.0, -6.0)]
    track = bundled_map("via_town")
    scene = build_scene(track)
    img = draw_topdown(scene, marks=[(10.0, -6.0)], marks_label="off the road", legend="driven path")
    x0, y1, k, w, h = minimap_frame(track)
    u, v = int(round((10.0 - x0) * k)), int(round((y1 + 6.0) * k))
    near = img[v - 6:v + 7, u - 6:u + 7].reshape(-1, 3).astype(int)
    assert (np.abs(near - MARK_BGR).sum(axis=1) < 40).sum() > 8  # a yellow cross there
    strip = img[h:].reshape(-1, 3).astype(int)
    assert (np.abs(strip - MARK_BGR).sum(axis=1) < 40).sum() > 8  # and its legend entry


def test_the_map_pictures_start_dot_is_where_the_car_starts_not_where_the_lap_begins():
    # A lap is the cycle the road from the start falls into; on procedural seed 138 the car
    # starts on a road that leads into it, and the dot was drawn at the cycle's first point.
    from signlane.world.procedural import generate_map
    from signlane.world.topdown import draw_topdown, minimap_frame
    track = Track.from_via(generate_map(138))
    lap = Route.loop(track).lane
    start = np.asarray(track.start_state()[3], float)
    assert np.hypot(*(lap[0] - start)) > 20.0  # this map's lap does begin elsewhere
    img = draw_topdown(build_scene(track), path_xy=lap, start_xy=start)
    x0, y1, k, _, _ = minimap_frame(track)

    def green_near(xy):
        u, v = int(round((xy[0] - x0) * k)), int(round((y1 - xy[1]) * k))
        near = img[v - 3:v + 4, u - 3:u + 4].reshape(-1, 3).astype(int)
        return (np.abs(near - (0, 255, 0)).sum(axis=1) < 60).sum()

    assert green_near(start) > 10 and green_near(lap[0]) == 0


@pytest.mark.parametrize("style", ["painted", "via"])
def test_a_camera_low_over_the_road_sees_road_to_the_bottom_of_the_frame(style):
    """A toy car's camera, 0.2 m up pitched 25 degrees down with a wide lens, sees the ground
    0.1 m ahead at its bottom row: road there, in the picture and in the truth (the ground nearer
    than a fixed near plane used to be left unpainted: verge in the picture and not road in the
    truth, right under the car)."""
    track = bundled_map("loop_demo", style=style)
    route, renderer = Route.loop(track), Renderer(build_scene(track, seed=3))
    cam = Camera(width=320, height=240, height_m=0.2, pitch_deg=25.0, hfov_deg=110.0)
    smp = renderer.render_on_route(route, _straight_s(route), cam)
    road = smp.truth.drivable_mask > 0
    assert road[-20:, 100:220].all()  # the bottom rows ahead of the car are road
    near = smp.image[-20:, 100:220].reshape(-1, 3).mean(0)
    mid = smp.image[150:170, 140:180].reshape(-1, 3).mean(0)  # road a little further on
    assert np.abs(near - mid).max() < 25, (near, mid)  # and look like it


def test_junction_focused_frames_have_a_junction_just_ahead():
    """`junctions` places that share of the frames 1-30 m before a junction of the route (the
    truth's junction distance); frames placed anywhere have one that near far less often."""
    def near_share(share: float) -> float:
        sampler = FrameSampler(3, SamplerConfig(style="mixed", effects="clean", junctions=share))
        near = 0
        for i in range(0, 200, 5):  # 8 tracks, 5 frames each
            j = sampler.sample(i).truth.junction
            near += j is not None and j.distance <= 30.5
        return near / 40

    assert near_share(1.0) == 1.0
    assert near_share(0.0) < 0.5
