"""S4 `vector-spline`: skeleton edges, scan lines, lane vectors, non-uniform B-spline boundaries.

Published (the paper, `VectorSplineParams.published()`), in the camera image as the paper works:
Canny edges thinned to 1 px by a morphological skeleton; two scan lines near the bottom of the
road area, scanned from the image's middle outwards for the first edge pixel, give two control
points (a lane vector) per side; 3 more scan lines split the rest of the road area into 4 bands.
On each, the next control point is predicted by extending the side's last lane vector, the row
is scanned from the midpoint of the two predictions outwards, and a hit whose direction turns
more than DELTA_ANGLE from the last vector (or no hit) is replaced by the prediction. Each side
is a non-uniform (chord-length) B-spline through its control points, cubic with 4+ points,
quadratic with 3. A side fails when its first two control points are not found. Per-side
curvature comes from the angles of the lane vectors over four scan lines (2nd to 5th points).

Robust default, in a metric bird's-eye view (a straight lane is straight there at any camera
pitch, angles and the lane-width prior are in metres, and far rows are not squeezed into a few
pixels): the edges are the centre lines of bright narrow stripes (paint), specks dropped, instead
of Canny (which also fires on shadow borders and the road edge); more scan lines; the first two
control points may come from any of the nearest scan lines (a dashed line's gap or the camera's
narrow near view) if they run ahead on nearby lines; later points are the edge nearest the
prediction within a margin; trailing predictions are not kept; sides are checked against the
lane-width prior (a lone far edge of a two-lane road is not the ego boundary), a pair is fitted with
one shared shape, and a view twice as deep is tried when the near one shows no line.

Boundaries are reported like every method: spline samples -> ground metres -> `fit_boundary` ->
`estimate_from_fits`; the spline's own per-side curvature is kept in the returned state.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np
from scipy.interpolate import make_interp_spline

from signlane.angles import wrap_pi
from signlane.camera import Camera
from signlane.lanes import register
from signlane.lanes.geometry import DEFAULT_LANE_WIDTH_M, Boundary, camera_for, estimate_from_fits, fit_boundary
from signlane.lanes.bev_marking import ego_birdseye, parallel, parallel_fits, plausible, ridge_mask, visible_mask
from signlane.types import LaneEstimate

NAME = "vector-spline"


@dataclass(frozen=True)
class VectorSplineParams:
    """Parameters; defaults are the robust variant, `published()` the paper's."""

    space: str = "bev"  # "image": Canny + skeleton in the camera image (the paper) | "bev": see module doc
    blur: int = 5  # image space: Gaussian kernel before Canny (the paper gives none; a common choice)
    canny: tuple[int, int] = (50, 150)  # image space: Canny thresholds (ditto)
    base_rows: tuple[float, float] = (0.03, 0.12)  # image space: the two first scan lines, fraction of
    n_bands: int = 4  # the road area up from the bottom; the rest is split into n_bands bands
    x_half_m: float = 7.0  # bird's-eye: half width, ground metres
    depth_m: float = 8.0  # bird's-eye: depth from the nearest visible ground ...
    retry_depth_m: float = 16.0  # ... and when that shows no line, this (0 = no retry)
    px_per_m: tuple[float, float] = (16.0, 8.0)
    row_step_m: float = 0.6  # bird's-eye: one scan line every this many metres
    ridge_m: float = 0.35  # bird's-eye stripe mask, see sliding_window.ridge_mask; stricter than
    ridge_rel: float = 0.15  # sliding-window's because the first mark out from the car is taken
    ridge_min: float = 10.0
    ridge_along_m: float = 0.6
    ridge_across_px: int = 3
    ridge_noise_k: float = 0.0
    thin: str = "runs"  # bird's-eye: 1-px edges by stripe "runs" centres or the paper's "skeleton"
    min_speck_px: int = 20  # edge components smaller than this are dropped (0 = keep all)
    start_rows: int = 0  # the first two control points come from the first start_rows scan lines (0: 60 %)
    delta_angle_deg: float = 30.0  # DELTA_ANGLE (not given in our summary of the paper)
    search: str = "near"  # "outward" from the predictions' midpoint (paper) | "near" the prediction
    margin_m: float = 0.3  # "near" search: a hit must be this close to the prediction
    min_hits: int = 3  # real (not predicted) control points a side needs
    keep_trailing: int = 0  # predictions kept after the last real hit (the paper keeps them all)
    validate: bool = True  # lane-width prior and plausibility checks on the sides
    fit_near_m: float = 8.0  # the reported fit uses the nearest this many metres of each spline
    lane_width_m: float = DEFAULT_LANE_WIDTH_M

    @classmethod
    def published(cls) -> VectorSplineParams:
        return cls(space="image", min_speck_px=0, start_rows=2, search="outward", min_hits=2,
                   keep_trailing=10 ** 6, validate=False, fit_near_m=np.inf, retry_depth_m=0.0)


@dataclass
class VectorSplineState:
    """Per-frame results kept for the caller: lane width used for a missing side and the
    spline's own curvature per side (1/m, + = bends right; nan where a side failed)."""

    lane_width_m: float = DEFAULT_LANE_WIDTH_M
    curvature_left: float = math.nan
    curvature_right: float = math.nan


def skeletonize(mask: np.ndarray) -> np.ndarray:
    """Morphological skeleton (Lantuejoul) of a uint8 (H, W) 0/255 mask -> uint8 0/255: the union
    over erosion depths of what an opening removes. 1-px lines (Canny edges) stay as they are."""
    kernel = cv2.getStructuringElement(cv2.MORPH_CROSS, (3, 3))
    img = (mask > 0).astype(np.uint8) * 255
    skel = np.zeros_like(img)
    while cv2.countNonZero(img):
        eroded = cv2.erode(img, kernel)
        skel |= cv2.subtract(img, cv2.dilate(eroded, kernel))
        img = eroded
    return skel


def run_centres(mask: np.ndarray) -> np.ndarray:
    """Row-wise thinning of a uint8 (H, W) 0/255 mask -> uint8 0/255 with the middle pixel of every
    horizontal run: the centre line of stripes that run up the view, without the spurs a
    morphological skeleton grows at a blob's corners."""
    m = np.zeros((mask.shape[0], mask.shape[1] + 2), np.int8)
    m[:, 1:-1] = mask > 0
    d = np.diff(m, axis=1)
    rs, starts = np.nonzero(d == 1)
    _, ends = np.nonzero(d == -1)  # row-major order: the k-th end closes the k-th start
    out = np.zeros(mask.shape, np.uint8)
    out[rs, (starts + ends - 1) // 2] = 255
    return out


@dataclass
class _View:
    """Where the scan runs: an edge image, its scan rows (bottom first), the column the scan starts
    from, pixel -> ground metres, and metres per column/row (1, 1 in the image: angles in pixels)."""

    edges: np.ndarray  # uint8 (h, w) 0/255, 1-px skeleton: what the scan lines look at
    marks: np.ndarray  # uint8 (h, w) 0/255 before thinning: reported as the debug mask
    rows: list[int]
    centre: float
    to_ground: Callable[[np.ndarray], np.ndarray]  # (N, 2) view pixels -> (N, 2) ground metres
    m_per_px: tuple[float, float]
    start_rows: int
    margin_px: float
    to_image: np.ndarray | None  # homography view -> camera image (None: the view is the image)


@register(NAME, VectorSplineParams)
def vector_spline(image_bgr: np.ndarray, camera: Camera | None, params: VectorSplineParams,
                  state: VectorSplineState | None) -> tuple[LaneEstimate, VectorSplineState]:
    """Lane from a uint8 (H, W, 3) BGR frame; see the module docstring for the steps."""
    image_bgr = image_bgr if image_bgr.ndim == 3 else cv2.cvtColor(image_bgr, cv2.COLOR_GRAY2BGR)
    h, w = image_bgr.shape[:2]
    width = state.lane_width_m if state is not None else params.lane_width_m
    if min(h, w) < 16:  # too small to hold a lane marking
        return LaneEstimate(NAME, False, debug_mask=np.zeros((h, w), np.uint8)), VectorSplineState(width)
    cam = camera_for(image_bgr, camera)
    out = _detect(image_bgr[:, :, :3], cam, params, params.depth_m)
    if out[0] is None and out[1] is None and params.space == "bev" and params.retry_depth_m > params.depth_m:
        # no line near the car: look further ahead (less accurate there, better than nothing)
        out = _detect(image_bgr[:, :, :3], cam, params, params.retry_depth_m)
    left, right, conf, debug, curv = out
    est = estimate_from_fits(NAME, cam, left, right, width, conf, debug)
    return est, VectorSplineState(width, *curv)


def _detect(image_bgr: np.ndarray, cam: Camera, p: VectorSplineParams, depth_m: float):
    """(left, right Boundary | None, confidence, debug mask uint8 (H, W), (curvature left, right))
    of a BGR uint8 frame; depth_m is the bird's-eye depth (space "bev")."""
    view = _image_view(image_bgr, cam, p) if p.space == "image" else _bev_view(image_bgr, cam, p, depth_m)
    sides = _trace(view, p)
    splines = [_spline_points(pts) if pts is not None else None for pts, _ in sides]
    fits, ground = [], []
    for sp in splines:
        g = None if sp is None else _near(view.to_ground(sp), p.fit_near_m)
        ground.append(g)
        fits.append(None if g is None else fit_boundary(g))
    left, right = fits
    fills = [0.0 if pts is None else float(np.mean(hits)) for pts, hits in sides]
    if p.validate:
        left, right = _check(left, right, ground, fills, p)
    curv = tuple(_curvature(view, sides[i][0]) if b is not None else math.nan for i, b in enumerate((left, right)))
    found = [b is not None for b in (left, right)]
    # confidence: the share of control points that were real edges, not predictions
    fills = [f if ok else 0.0 for f, ok in zip(fills, found)]
    conf = 0.5 * (fills[0] + fills[1]) if all(found) else 0.6 * max(fills)  # one side: the other is a guess
    return left, right, float(conf), _debug_mask(view, splines, found, cam), curv


def _near(g: np.ndarray, span_m: float) -> np.ndarray:
    """Ground points (N, 2) within span_m of the nearest: a quadratic follows a bend only briefly."""
    g = g[np.all(np.isfinite(g), axis=1)]
    return g[g[:, 1] < g[:, 1].min() + span_m] if len(g) else g


def _image_view(image_bgr: np.ndarray, cam: Camera, p: VectorSplineParams) -> _View:
    """The paper's setting: edges of the camera image; scan lines span the road area below the
    horizon (found from the camera model), two near the bottom and n_bands - 1 over the rest."""
    h, w = image_bgr.shape[:2]
    gray = cv2.cvtColor(image_bgr, cv2.COLOR_BGR2GRAY)
    if p.blur > 1:
        gray = cv2.GaussianBlur(gray, (p.blur | 1, p.blur | 1), 0)
    marks = _clean(cv2.Canny(gray, *p.canny), p)
    n, c = cam.horizon()  # rows below the horizon line at the image centre see the road
    v_h = -(n[0] * w / 2 + c) / n[1] if abs(n[1]) > 1e-9 else 0.0
    top = float(np.clip(v_h, 0, h - 2)) + 0.1 * (h - float(np.clip(v_h, 0, h - 2)))
    span = h - 1 - top
    r1, r2 = (h - 1 - f * span for f in p.base_rows)
    rows = [r1, r2] + [r2 - k * (r2 - top) / p.n_bands for k in range(1, p.n_bands)]
    rows = sorted({round(r) for r in rows}, reverse=True)  # a tiny image may round two to one row
    return _View(skeletonize(marks), marks, rows, w / 2.0, cam.image_to_ground,
                 (1.0, 1.0), p.start_rows or 2, 0.1 * w, None)


def _bev_view(image_bgr: np.ndarray, cam: Camera, p: VectorSplineParams, depth_m: float) -> _View:
    """A metric bird's-eye view: stripe centres, a scan line every row_step_m, scans from the car."""
    bev = ego_birdseye(cam, p.x_half_m, depth_m, p.px_per_m)
    sx, sy = bev.px_per_m
    mask = ridge_mask(bev.warp(image_bgr), visible_mask(bev), round(p.ridge_m * sx), p.ridge_rel, p.ridge_min,
                      round(p.ridge_along_m * sy), p.ridge_across_px, p.ridge_noise_k)
    mask = _clean(mask, p)
    step = max(1, round(p.row_step_m * sy))
    rows = list(range(bev.size[1] - 1 - step // 2, -1, -step))
    start = p.start_rows or max(2, int(0.6 * len(rows)))  # a dashed gap or a narrow near view
    return _View(run_centres(mask) if p.thin == "runs" else skeletonize(mask), mask, rows, -bev.x_range_m[0] * sx,
                 bev.bev_to_ground, (1 / sx, 1 / sy), start, p.margin_m * sx, bev.bev_to_image_h())


def _clean(mask: np.ndarray, p: VectorSplineParams) -> np.ndarray:
    """Drop specks: paint is a stripe, texture noise a few pixels."""
    if p.min_speck_px <= 0:
        return mask
    n, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
    keep = np.zeros(n, np.uint8)
    keep[1:] = (stats[1:, cv2.CC_STAT_AREA] >= p.min_speck_px).astype(np.uint8) * 255
    return keep[labels]


def _first_from(cols: np.ndarray, start: float, sign: int) -> float | None:
    """The first edge column from `start` going left (sign -1) or right (+1)."""
    side = cols[cols < start] if sign < 0 else cols[cols > start]
    if not len(side):
        return None
    return float(side.max() if sign < 0 else side.min())


def _angle(a, b, m_per_px) -> float:
    """Direction (rad) of the vector a -> b, measured from 'ahead' (up the view), + to the right."""
    return math.atan2((b[0] - a[0]) * m_per_px[0], (a[1] - b[1]) * m_per_px[1])


def _turn(pts: list, new, m_per_px) -> float:
    """|Change of direction| (rad) from the last lane vector to the one ending at `new`."""
    d = _angle(pts[-1], new, m_per_px) - _angle(pts[-2], pts[-1], m_per_px)
    return abs(wrap_pi(d))


def _trace(view: _View, p: VectorSplineParams):
    """Control points per side: [(points (N,2) view pixels, real-hit flags (N,)) or (None, None)]
    for the left and the right boundary, following the scan lines bottom to top."""
    e = view.edges
    h, w = e.shape
    delta = math.radians(p.delta_angle_deg)
    pts, hits, dead, rows_at = [[], []], [[], []], [False, False], [0, 0]
    for i, r in enumerate(view.rows):
        if not 0 <= r < h:
            continue
        cols = np.flatnonzero(e[r])
        preds = [_predict(pts[s], r) if len(pts[s]) >= 2 and not dead[s] else None for s in (0, 1)]
        mid = 0.5 * (preds[0] + preds[1]) if None not in preds else view.centre
        for s, sign in ((0, -1), (1, 1)):
            if dead[s]:
                continue
            if len(pts[s]) < 2:  # the lane vector: first two control points
                dead[s] = i >= view.start_rows
                c = None if dead[s] else _first_from(cols, view.centre, sign)
                if c is not None:
                    if len(pts[s]) == 1 and not _starts_lane(pts[s][0], (c, r), i - rows_at[s], view, p):
                        pts[s], hits[s] = [], []  # not a line running ahead: start again here
                    pts[s].append((c, r))
                    hits[s].append(True)
                    rows_at[s] = i
                continue
            pred = preds[s]
            if not 0 <= pred < w:  # the line leaves the view
                dead[s] = True
                continue
            c = _find(cols, pred, mid, sign, view, p)
            if c is not None and _turn(pts[s], (c, r), view.m_per_px) > delta:
                c = None  # turns too sharply for a lane: noise
            pts[s].append((pred if c is None else c, r))
            hits[s].append(c is not None)
    return [_finish(pts[s], hits[s], p) for s in (0, 1)]


def _starts_lane(a, b, gap_rows: int, view: _View, p: VectorSplineParams) -> bool:
    """Robust variant: two hits make the first lane vector if they run roughly ahead on nearby
    scan lines (a speck, then a line further up, is no vector). The paper takes any two."""
    return not p.validate or (abs(_angle(a, b, view.m_per_px)) < math.radians(45) and gap_rows <= 2)


def _predict(pts: list, r: float) -> float:
    """Column where the last lane vector, extended, crosses row r."""
    (x1, y1), (x2, y2) = pts[-2], pts[-1]
    return x2 + (x2 - x1) * (r - y2) / (y2 - y1) if y2 != y1 else x2


def _find(cols: np.ndarray, pred: float, mid: float, sign: int, view: _View, p: VectorSplineParams):
    """The edge column for a predicted control point, or None."""
    if p.search == "near":
        if not len(cols):
            return None
        j = int(np.argmin(np.abs(cols - pred)))
        return float(cols[j]) if abs(cols[j] - pred) <= view.margin_px else None
    return _first_from(cols, mid, sign)


def _finish(pts: list, hits: list, p: VectorSplineParams):
    """(points (N, 2), hit flags (N,)) of a side that found its lane vector, else (None, None)."""
    if len(pts) < 2 or sum(hits[:2]) < 2 or sum(hits) < p.min_hits:
        return None, None  # the paper's failure: no lane vector (or too little of a line)
    last = max(i for i, hit in enumerate(hits) if hit)
    pts, hits = pts[: last + 1 + p.keep_trailing], hits[: last + 1 + p.keep_trailing]
    return np.array(pts, np.float64), np.array(hits, bool)


def _spline_points(pts: np.ndarray, per_span: int = 6) -> np.ndarray | None:
    """Samples (M, 2) along the non-uniform B-spline through the control points: the knots follow
    the chord lengths; cubic with 4+ points, quadratic with 3, a segment with 2."""
    d = np.hypot(*np.diff(pts, axis=0).T)
    keep = np.concatenate([[True], d > 1e-6])
    pts, d = pts[keep], d[d > 1e-6]
    if len(pts) < 2:
        return None
    u = np.concatenate([[0.0], np.cumsum(d)])
    spline = make_interp_spline(u, pts, k=min(3, len(pts) - 1))
    return spline(np.linspace(0.0, u[-1], per_span * (len(pts) - 1) + 1))


def _check(left: Boundary | None, right: Boundary | None, ground: list, fills: list, p: VectorSplineParams):
    """Sides against the lane-width prior: each on its side of the car and plausible; a pair a
    lane apart and parallel (then fitted with one shape), or the weaker side is dropped."""
    left = left if plausible(left, -1) else None
    right = right if plausible(right, +1) else None
    if left is None or right is None:
        # a lone line is a boundary of the car's lane only within about a lane width of the car
        reach = 1.05 * p.lane_width_m
        return (left if left is not None and left.x_at(0.0) > -reach else None,
                right if right is not None and right.x_at(0.0) < reach else None)
    y = max(left.y_range[0], right.y_range[0])
    if right.x_at(y) - left.x_at(y) > 1.6 * p.lane_width_m:
        return None, right  # scanning out from the car found the far edge of a two-lane road
    if not parallel(left, right, p.lane_width_m):
        return (left, None) if fills[0] * left.support > fills[1] * right.support else (None, right)
    both = parallel_fits(ground[0], ground[1])
    return both if both is not None else (left, right)


def _curvature(view: _View, pts: np.ndarray) -> float:
    """The paper's per-side curvature (1/m, + = bends right): the directions of the three lane
    vectors between four scan lines (the 2nd to the 5th control points; spread over the side's
    control points when there are more), their changes per metre, weighted to the nearer one.
    nan with fewer than three control points."""
    idx = np.unique(np.round(np.linspace(1 if len(pts) > 4 else 0, len(pts) - 1, 4)).astype(int))
    g = view.to_ground(pts[idx])
    g = g[np.all(np.isfinite(g), axis=1)]
    if len(g) < 3:
        return math.nan
    v = np.diff(g, axis=0)
    theta = np.arctan2(v[:, 0], v[:, 1])  # from ahead, + to the right: grows along a right bend
    length = np.hypot(v[:, 0], v[:, 1])
    k = np.diff(theta) / np.maximum(0.5 * (length[1:] + length[:-1]), 1e-6)
    weights = np.arange(len(k), 0, -1, dtype=np.float64)
    return float(np.dot(k, weights) / weights.sum())


def _debug_mask(view: _View, splines: list, found: list, cam: Camera) -> np.ndarray:
    """uint8 (H, W) 0/255 in the camera image: the edge pixels along the kept boundaries."""
    along = np.zeros_like(view.edges)
    for sp, ok in zip(splines, found):
        if ok and sp is not None:
            cv2.polylines(along, [np.round(sp).astype(np.int32)], False, 255, 5)
    mask = view.marks & along
    if view.to_image is None:
        return mask
    return cv2.warpPerspective(mask, view.to_image, (cam.width, cam.height), flags=cv2.INTER_NEAREST)
