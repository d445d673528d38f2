"""Renderer: determinism by seed and ground truth that agrees with the pixels."""
import json
import math
from importlib import resources

import numpy as np
import pytest

from signlane.camera import Camera
from signlane.world.effects import Effects
from signlane.world.render import Renderer
from signlane.world.route import Route
from signlane.world.sampling import FrameSampler, SamplerConfig
from signlane.world.scene import build_scene
from signlane.world.track import Track, WorldObject

LOOP = json.loads(resources.files("signlane.world").joinpath("maps/loop_demo.json").read_text())


@pytest.fixture(scope="module")
def loop():
    track = Track.from_via(LOOP)
    return track, Route.loop(track), Renderer(build_scene(track, seed=3))


def test_same_seed_same_pixels_other_seed_other_pixels():
    cfg = SamplerConfig(effects="hard")
    a = FrameSampler(11, cfg).sample(7)
    b = FrameSampler(11, cfg).sample(7)
    c = FrameSampler(12, cfg).sample(7)
    assert np.array_equal(a.image, b.image) and np.array_equal(a.truth.marking_mask, b.truth.marking_mask)
    assert a.truth.to_label() == b.truth.to_label()
    assert np.mean(np.abs(a.image.astype(int) - c.image.astype(int))) > 5


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
            continue  # markings stop inside junctions
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


def test_offset_and_heading_signs_follow_the_pose(loop):
    track, route, renderer = loop
    cam = Camera()
    s = 20.0
    right = renderer.render_on_route(route, s, cam, lateral_m=0.8).truth
    left = renderer.render_on_route(route, s, cam, lateral_m=-0.8).truth
    lw = track.style.lane_width
    assert right.offset == pytest.approx(0.8 / lw, abs=0.01)
    assert left.offset == pytest.approx(-0.8 / lw, abs=0.01)
    # when the car is right of centre, the lane centre appears left of the image centre
    assert right.center[0, 0] < cam.width / 2 < left.center[0, 0]
    turned = renderer.render_on_route(route, s, cam, heading_offset=math.radians(5)).truth
    assert turned.heading == pytest.approx(math.radians(5), abs=1e-3)
    # pointing right of the lane: the lane ahead drifts to the left of the image
    assert turned.center[-1, 0] < cam.width / 2


def test_curvature_sign_on_a_left_and_a_right_bend():
    ring = {"map_name": "ring", "map_size": {"x": 4, "y": 4},
            "cell_datas": [{"id_inmap": 5, "tile_id": 2, "rot": 0}, {"id_inmap": 6, "tile_id": 2, "rot": 90},
                           {"id_inmap": 10, "tile_id": 2, "rot": 180}, {"id_inmap": 9, "tile_id": 2, "rot": 270}]}
    track = Track.from_via(ring, cell_m=10.0)
    renderer = Renderer(build_scene(track))
    for reverse in (False, True):
        route = Route.loop(track, reverse=reverse)
        t = renderer.render_on_route(route, 5.0, Camera()).truth
        # the route's own turning direction decides the sign; |k| is 1/15 m
        expected = float(np.sign(np.median(route.curvature)))
        assert np.sign(t.curvature) == expected and abs(abs(t.curvature) - 1 / 15) < 0.01
        # bending right: the far lane centre is right of the near one in the image
        assert np.sign(t.center[-1, 0] - t.center[0, 0]) == expected


def test_sign_box_contains_its_rendered_pixels(loop):
    track, route, _ = loop
    s0, _ = route.project(*route.lane[0])
    pose = route.pose_at(s0 + 30.0)
    # a stop sign 12 m ahead on the right, facing the car
    f, r = pose.forward, pose.right
    p = np.array([pose.x, pose.y]) + 12.0 * f + 3.5 * r
    sign = WorldObject("stop", float(p[0]), float(p[1]), pose.heading + math.pi, seed=1)
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
    s0, _ = route.project(*route.lane[0])
    pose = route.pose_at(s0 + 30.0)
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


def test_effects_change_pixels_not_truth(loop):
    _, route, renderer = loop
    cam = Camera()
    clean = renderer.render_on_route(route, 50.0, cam, effects=Effects(noise=10, jpeg_prob=1.0),
                                     rng=np.random.default_rng(1))
    plain = renderer.render_on_route(route, 50.0, cam)
    assert not np.array_equal(clean.image, plain.image)
    assert np.array_equal(clean.truth.marking_mask, plain.truth.marking_mask)
