"""The junction detector's colour rule for road, in integer Lab boxes (cv2.inRange), is the rule
as written: within lab_tol of the patch ahead's median (its integer part), or darker than it
down to shadow_floor of it with the same tint, or paint (25 lighter, colourless); seen ground
only; specks opened away."""
import cv2
import numpy as np

from signlane.camera import via_camera
from signlane.junction import JunctionDetector


def _rule(det: JunctionDetector, image: np.ndarray) -> np.ndarray:
    p = det.p
    lab = cv2.cvtColor(det.bev.warp(image), cv2.COLOR_BGR2LAB).astype(np.int16)
    rows = slice(int((p.y_range_m[1] - p.y_range_m[0] - 3.0) * p.px_per_m), int((p.y_range_m[1] - p.y_range_m[0]) * p.px_per_m))
    ref = np.median(lab[rows, det._col(-0.9):det._col(0.9)].reshape(-1, 3), axis=0)
    d = np.abs(lab - ref.astype(np.int16))
    light = (d[..., 0] < p.lab_tol[0]) | ((lab[..., 0] < ref[0]) & (lab[..., 0] > p.shadow_floor * ref[0]))
    road = light & (d[..., 1] < p.lab_tol[1]) & (d[..., 2] < p.lab_tol[2])
    paint = (lab[..., 0] > ref[0] + 25) & (np.abs(lab[..., 1] - 128) < 20)
    mask = ((road | paint) & det.visible).astype(np.uint8) * 255
    return cv2.morphologyEx(mask, cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))


def test_the_road_mask_is_the_rule_on_every_kind_of_frame():
    det = JunctionDetector(via_camera(320, 240))
    rng = np.random.default_rng(5)
    frames = []
    for _ in range(60):
        img = np.empty((240, 320, 3), np.uint8)
        img[:120] = rng.integers(0, 256, 3)  # sky
        img[120:] = rng.integers(0, 256, 3)  # ground of one colour, then texture, shadows and paint on it
        img[120:] = np.clip(img[120:].astype(int) + rng.integers(-40, 40, (120, 320, 1)), 0, 255)
        cv2.rectangle(img, (int(rng.integers(0, 300)), 150), (int(rng.integers(0, 320)), 239),
                      tuple(int(v) for v in rng.integers(0, 256, 3)), -1)
        cv2.line(img, (160, 239), (int(rng.integers(100, 220)), 130), (250, 250, 250), 3)
        frames.append(img)
    frames += [np.full((240, 320, 3), v, np.uint8) for v in (0, 1, 128, 231, 254, 255)]
    for img in frames:
        want, got = _rule(det, img), det.road_mask(img)
        assert np.array_equal(want, got), int((want != got).sum())
    assert any(det.road_mask(f).any() for f in frames) and not all(det.road_mask(f).all() for f in frames)


def _reaches_by_walking(scan, us, vs, sgn, verge, p):
    """_row_reaches' rule, row by row and pixel by pixel outwards from the edge."""
    w = scan.road.shape[1]
    k = scan.bev.px_per_m[0]
    n = max(2, int(round(p.end_seen_m * k)))
    out = []
    for u, v in zip(us, vs):
        road, vis, verge_px = [], [], []
        for j in range(w):
            c = int(u) + (j if sgn > 0 else -j)
            inside = 0 <= c < w
            c = min(max(c, 0), w - 1)
            r, s = bool(scan.road[v, c]) and inside, bool(scan.visible[v, c]) and inside
            lab = scan.lab[v, c].astype(float)
            road.append(r)
            vis.append(s)
            verge_px.append(s and not r and abs(lab[0] - verge[0]) < 30 and abs(lab[1] - verge[1]) < 12
                            and abs(lab[2] - verge[2]) < 12)
        start = next((j for j in range(w - n + 1) if all(verge_px[j:j + n])), None)
        seen_road = [j for j in range(w) if road[j] and vis[j]]
        if not any(vis):
            out.append(("unknown", 0.0))
        elif start is not None:
            before = [j for j in seen_road if j < start]
            out.append(("end", float(before[-1] + 1) / k) if before else ("unknown", 0.0))
        elif seen_road and max(j for j in range(w) if vis[j]) - seen_road[-1] <= 0.5 * k:
            out.append(("on", float(seen_road[-1]) / k))
        else:
            out.append(("unknown", 0.0))
    return out


def test_row_reaches_follow_each_row_outwards_as_a_walk_along_it_does():
    """The side-road reach of every row of carriageway scans before junctions (VIA's look), both
    sides, with a verge colour of each scan's own ground: as walking each row pixel by pixel."""
    from signlane import junction
    from signlane.lanes.road_edges import RoadEdgesParams, RoadEdgesState, carriageway
    from signlane.world.sampling import DriveSampler, SamplerConfig
    cam = via_camera(320, 240)
    sampler = DriveSampler(5, SamplerConfig(320, 240, style="via", effects="normal", randomise=False, junctions=1.0))
    p = junction.ScanJunctionParams()
    checked = ends = 0
    for i in range(6):
        scan = carriageway(sampler.sample(i).image, cam, RoadEdgesParams(), RoadEdgesState())[3].scan
        h, w = scan.road.shape
        vs = np.arange(0, h, 3)
        # the ground's commonest colour, and verge colours that put it exactly at a threshold's
        # distance (not verge) or just inside it, channel by channel
        values, counts = np.unique(scan.lab[scan.visible & ~scan.road], axis=0, return_counts=True)
        ground = values[np.argmax(counts)].astype(float)
        verges = [ground, ground + (30, 0, 0), ground - (29.5, 0, 0), ground - (0, 12, 0), ground + (0, 11.5, 12)]
        for j, verge in enumerate(verges):
            sgn = 1 if j % 2 else -1
            us = np.full(len(vs), w // 2 + sgn * 20)
            got = junction._row_reaches(scan, us, vs, sgn, verge, p)
            assert got == _reaches_by_walking(scan, us, vs, sgn, verge, p)
            checked += len(got)
            ends += sum(kind == "end" for kind, _ in got)
    assert checked > 300 and ends > 20
