"""S2 `sliding-window`: bird's-eye binary, histogram bases, sliding windows, quadratic fits.

Published (the S2 report, `SlidingWindowParams.published()`): warp the ground that the source's
1280x720 trapezoid covered (about 1.5 lane widths across, 30 m deep, from the row at 680/720) to a
bird's-eye image of the frame's size; binary = Sobel-x on HLS lightness (|grad| scaled to 0..255,
kept in 20..100) OR HLS saturation in 170..255; the column histogram of the bottom half gives one
base per half; 9 windows 200/1280 of the width wide climb each line, re-centred on the mean x of
the pixels inside; a 2nd-order fit per side. With a state, the next frame searches a margin around
the previous fits instead of the histogram.

Robust default: a metric bird's-eye view 8 m deep (16 m when that shows no line); the binary keeps
bright narrow stripes (paint is brighter than the road on both sides; shadow borders and road edges
are one-sided steps) with a yellowness term, standing out from the road's own texture (adaptive,
where the report's fixed S-channel threshold finds nothing on grey roads); the base histogram is
sheared and bent to the lines' common heading and curvature; windows follow that shape through gaps
and need a minimum of pixels; every base is climbed and the ego lane is the pair of lines a lane
width apart around the car (a lone line is the nearer boundary on its side; the far edge of a
two-lane road without a centre line is recognised and not used); a pair is fitted with one shared
shape over its nearest 8 m; an implausible side is dropped and the lane-width fallback places it.
Tracking searches around the last fits and keeps a measured lane width.

The bird's-eye, stripe-mask, pairing and checking helpers live in `bev_marking` (shared with
`vector_spline`).
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np

from signlane import order_stats
from signlane.camera import BirdsEye, Camera
from signlane.lanes import register
from signlane.lanes.bev_marking import (ego_birdseye, histogram_peaks, parallel, parallel_fits, pick_ego_pair,
                                        plausible, ridge_mask, sobel_s_mask, visible_mask, width_between)
from signlane.lanes.geometry import (DEFAULT_LANE_WIDTH_M, Boundary, camera_for,
                                     estimate_from_fits, fit_boundary)
from signlane.types import LaneEstimate

NAME = "sliding-window"
SOURCE_NEAR_ROW = 680 / 720  # the trapezoid's bottom edge, as a fraction of the frame height
SOURCE_HALF_WIDTH_M = 2.8  # its bottom edge spans ~1.5 lane widths of 3.7 m
SOURCE_DEPTH_M = 30.0  # the report's 30 m per 720 bird's-eye rows


@dataclass(frozen=True)
class SlidingWindowParams:
    """Parameters; defaults are the robust variant, `published()` the S2 report's."""

    region: str = "view"  # "view": from the bottom row | "source": from the S2 trapezoid's near row
    x_half_m: float = 7.0  # bird's-eye half width, ground metres
    depth_m: float = 8.0  # bird's-eye depth from the nearest visible ground ...
    retry_depth_m: float = 16.0  # ... and when that shows no line, this (0 = no retry)
    px_per_m: tuple[float, float] | None = (16.0, 8.0)  # (x, y); None = bird's-eye of the frame's size
    binary: str = "ridge"  # "ridge" (bright narrow stripes) | "sobel-s" (the report's thresholds)
    sobel_thresh: tuple[int, int] = (20, 100)
    s_thresh: tuple[int, int] = (170, 255)
    ridge_m: float = 0.35  # lateral distance at which a stripe is compared with the road
    ridge_rel: float = 0.08  # a stripe beats both sides by this fraction of the road's brightness ...
    ridge_min: float = 8.0  # ... and by at least this much (0..255)
    ridge_along_m: float = 0.6  # brightness is averaged over this length ahead first
    ridge_noise_k: float = 2.0  # ... and beats this many times the road texture's contrast
    hist_rows: float = 0.5  # fraction of the bird's-eye (nearest rows) in the base histogram
    shear_max: float = 0.35  # histograms sheared by lateral slopes up to this (heading) ...
    bend_max: float = 0.075  # ... and bent by curvatures up to this (1/m); 0, 0 = plain histogram
    pair_bases: bool = True  # climb every base and pick the ego pair (False: argmax per half)
    n_windows: int = 9
    window_m: float = 0.8  # window width, ground metres
    min_fill: float = 0.08  # a window counts with this fraction of its pixels lit
    median: bool = True  # re-centre on the median x (robust to stray pixels) instead of the mean
    margin_m: float = 0.5  # search-around-previous-fit margin
    fit_near_m: float = 8.0  # each line is fitted over its nearest this many metres
    validate: bool = True  # drop implausible sides, fit pairs with one shape
    lane_width_m: float = DEFAULT_LANE_WIDTH_M
    min_support: int = 20  # fewer pixels than this and a side is not found
    # confidence: a line lighting this share of its windows counts as wholly found. A dashed
    # centre line cannot light them all (3 m dashes, 4 m gaps light 4 to 6 of 9): measured on
    # seeded painted frames, well-found dashed lines fill 0.33..0.67, so the mean of the raw fills
    # (about 0.67 beside a solid edge) fell short of autolabel's 0.7 on frames found to within
    # 0.03 lane widths
    full_fill: float = 0.45

    @classmethod
    def published(cls) -> SlidingWindowParams:
        # 200x80 windows and a 100 px margin at 1280x720 over the 5.6 m x 30 m region; minpix 50 of
        # the 16000 px window (the reference code the report follows)
        span = 2 * SOURCE_HALF_WIDTH_M
        return cls(region="source", x_half_m=SOURCE_HALF_WIDTH_M, depth_m=SOURCE_DEPTH_M, retry_depth_m=0.0,
                   px_per_m=None, binary="sobel-s", shear_max=0.0, bend_max=0.0, pair_bases=False,
                   n_windows=720 // 80, window_m=span * 200 / 1280, min_fill=50 / (200 * 80), median=False,
                   margin_m=span * 100 / 1280, fit_near_m=np.inf, validate=False, min_support=3)


@dataclass
class SlidingWindowState:
    """Tracking state: the last fits (ground metres) and lane width; `tracked` tells whether the
    last frame came from the search around the previous fits (True) or from the histogram."""

    left: Boundary | None = None
    right: Boundary | None = None
    lane_width_m: float = DEFAULT_LANE_WIDTH_M
    tracked: bool = False
    misses: int = 0
    # with debug_later: makes the last frame's debug mask (the kept lines' pixels in the frame),
    # for a caller that shows it after the frame's answer
    debug_later: Callable[[], np.ndarray] | None = None


# --- the method -----------------------------------------------------------------------------
@dataclass
class _Pixels:
    """The binary's lit pixels: bird's-eye columns and rows (N,), ground metres (N, 2); rows
    ascending (np.nonzero's order), so a band of rows is a slice."""

    us: np.ndarray
    vs: np.ndarray
    ground: np.ndarray


@dataclass
class _Line:
    """A line found: indices into _Pixels, the share of its windows (inside the camera's view)
    that found paint, the ground points (N, 2) behind its fit, and the fit."""

    idx: np.ndarray
    fill: float
    pts: np.ndarray
    fit: Boundary | None


def _line(px: _Pixels, idx: np.ndarray, fill: float, p: SlidingWindowParams) -> _Line:
    """A line from its pixels, fitted over its nearest `fit_near_m`: a quadratic follows a bend
    only over a short run, and the offset is read at the car (y = 0)."""
    pts = px.ground[idx]
    if len(pts) > 1500:  # plenty for a quadratic; keeps polyfit cheap
        pts = pts[:: len(pts) // 1500 + 1]
    if len(pts):
        pts = pts[pts[:, 1] < order_stats.quantile(pts[:, 1], 0.02) + p.fit_near_m]
    return _Line(idx, fill, pts, fit_boundary(pts))


@register(NAME, SlidingWindowParams)
def sliding_window(image_bgr: np.ndarray, camera: Camera | None, params: SlidingWindowParams,
                   state: SlidingWindowState | None, debug_later: bool = False
                   ) -> tuple[LaneEstimate, SlidingWindowState]:
    """Lane from a uint8 (H, W, 3) BGR frame; see the module docstring for the steps.
    debug_later: the estimate has no debug mask; the new state's `debug_later()` makes it."""
    image_bgr = image_bgr if image_bgr.ndim == 3 else cv2.cvtColor(image_bgr, cv2.COLOR_GRAY2BGR)
    h, w = image_bgr.shape[:2]
    state = state or SlidingWindowState(lane_width_m=params.lane_width_m)
    if min(h, w) < 16:  # too small to hold a lane marking
        return LaneEstimate(NAME, False, debug_mask=np.zeros((h, w), np.uint8)), _lost(state)
    cam = camera_for(image_bgr, camera)

    def binary_of(bev: BirdsEye, valid: np.ndarray) -> np.ndarray:
        return _binary(bev.warp(image_bgr[:, :, :3]), valid, bev, params)
    return lanes_from_binary(NAME, binary_of, cam, params, state, debug_later=debug_later)


def lanes_from_binary(name: str, binary_of, cam: Camera, params: SlidingWindowParams,
                      state: SlidingWindowState | None, debug_later: bool = False,
                      own_debug: bool = True) -> tuple[LaneEstimate, SlidingWindowState]:
    """The back-end after the binary, shared with the learned `segnet`: `binary_of(bev, valid)`
    gives the uint8 0/255 lane-paint mask of a bird's-eye view (valid = where it sees ground);
    bases, windows, ego pair, checks and fits follow. The debug mask is the kept lines' pixels;
    debug_later: none now, the new state's `debug_later()` makes it (a warp of the frame's size,
    which only a viewer of the mask reads); own_debug=False: none at all (the caller's estimate
    carries its own, e.g. segnet's put-off network mask)."""
    state = state or SlidingWindowState(lane_width_m=params.lane_width_m)
    want = "later" if debug_later else own_debug
    lb, rb, conf, debug, tracked = _detect(binary_of, cam, params, state, params.depth_m, want)
    if lb is None and rb is None and params.retry_depth_m > params.depth_m:
        # no line near the car: look further ahead (less accurate there, better than nothing)
        lb, rb, conf, debug, tracked = _detect(binary_of, cam, params, state, params.retry_depth_m, want)
    later = debug if debug_later else None
    shown = None if debug_later else debug
    est = estimate_from_fits(name, cam, lb, rb, state.lane_width_m, conf, shown)
    if not est.found:
        return est, _lost(state, later)
    width = state.lane_width_m
    if lb is not None and rb is not None and params.validate:
        # a measured pair steadies the width used when only one line is seen in later frames
        width = float(np.clip(0.7 * width + 0.3 * width_between(lb, rb), 0.75 * params.lane_width_m,
                              1.4 * params.lane_width_m))
    return est, SlidingWindowState(lb, rb, width, tracked, debug_later=later)


def _lost(state: SlidingWindowState, debug_later=None) -> SlidingWindowState:
    """After a miss: forget the fits (the next frame searches afresh), keep the lane width."""
    return SlidingWindowState(None, None, state.lane_width_m, False, state.misses + 1, debug_later)


def _detect(binary_of, cam: Camera, p: SlidingWindowParams, state: SlidingWindowState, depth_m: float,
            want_debug: bool | str = True):
    """(left, right Boundary | None, confidence, debug mask uint8 (H, W) | None, tracked) through
    a bird's-eye view depth_m deep whose binary `binary_of(bev, valid)` makes; want_debug
    "later": a function that makes the debug mask instead of the mask."""
    near = SOURCE_NEAR_ROW if p.region == "source" else 1.0
    bev = ego_birdseye(cam, p.x_half_m, depth_m, p.px_per_m, near)
    valid = visible_mask(bev)
    binary = binary_of(bev, valid)
    vs, us = np.nonzero(binary)
    px = _Pixels(us, vs, bev.bev_to_ground(np.column_stack([us, vs])))
    held = _search_around(px, bev, state, p) if state.left is not None or state.right is not None else (None, None)
    tracked = held[0] is not None or held[1] is not None
    if tracked and (held[0] is not None and held[1] is not None or not p.validate):
        left, right, kind = held[0], held[1], "pair"
    else:
        left, right, kind = _window_search(px, valid, bev, p, state.lane_width_m)
        if tracked:  # keep the side tracking held; the search fills the other
            left, right, kind = _fill_held(held, left, right, state.lane_width_m)
    lb, rb, conf = _boundaries(left, right, kind, p)
    if not want_debug:
        return lb, rb, conf, None, tracked
    kept = [line.idx for line, b in ((left, lb), (right, rb)) if line is not None and b is not None]

    def debug() -> np.ndarray:
        mask = np.zeros(binary.shape, np.uint8)
        for idx in kept:
            mask[vs[idx], us[idx]] = 255
        return cv2.warpPerspective(mask, bev.bev_to_image_h(), (cam.width, cam.height), flags=cv2.INTER_NEAREST)
    return lb, rb, conf, debug if want_debug == "later" else debug(), tracked


def _fill_held(held: tuple, left: _Line | None, right: _Line | None, lane_width_m: float):
    """(left, right, kind) when tracking holds one side: the search's line for the other side
    fills it only if the two keep a lane's width apart. The search pairs its own lines: in a
    tight bend, with the held edge line curving out of its windows, it can pick a neighbouring
    lane (the road's far edge and the centre line) whose right line lies left of the held one;
    pairing that lane's left line with the held right edge made a whole road of the lane, and
    the checks after kept the far edge as the ego lane's left (the car steered for the oncoming
    lane). A two-lane road's far edge ('wide') fails the same test."""
    keep = held[0] if held[0] is not None else held[1]
    fill = right if held[0] is not None else left
    if fill is not None and not parallel(*((keep.fit, fill.fit) if held[0] is not None else (fill.fit, keep.fit)),
                                         lane_width_m):
        fill = None
    return (keep, fill, "pair") if held[0] is not None else (fill, keep, "pair")


def _binary(view: np.ndarray, valid: np.ndarray, bev: BirdsEye, p: SlidingWindowParams) -> np.ndarray:
    """uint8 (h, w) 0/255 lane-paint candidates in the bird's-eye BGR view."""
    if p.binary == "ridge":
        return ridge_mask(view, valid, round(p.ridge_m * bev.px_per_m[0]), p.ridge_rel, p.ridge_min,
                          round(p.ridge_along_m * bev.px_per_m[1]), 1, p.ridge_noise_k)
    # the source's trapezoid lay inside the frame; ours may not: ignore the view's own border
    return sobel_s_mask(view, p.sobel_thresh, p.s_thresh) & cv2.erode(valid, np.ones((3, 3), np.uint8))


def _shape(px: _Pixels, bev: BirdsEye, p: SlidingWindowParams) -> tuple[float, float, np.ndarray]:
    """Lateral slope b and bend k (x = x0 + b t + k t^2 / 2, t = metres beyond the bottom row)
    that make the near pixels' histogram sharpest, and that histogram of x0 (columns)."""
    bw, bh = bev.size
    near = px.vs >= bh * (1.0 - p.hist_rows)
    us, vs = px.us[near], px.vs[near]
    bb, kk = _shape_grid(p.shear_max, p.bend_max)
    # x0 = x - b t - k t^2 / 2 in columns is the pixel's column less a shift that depends only on
    # its row (t is the row's distance): the shifts for every (b, k) and row first (a small
    # table), then one gather and subtraction over the (77, pixels) array
    v0 = int(vs.min()) if len(vs) else 0
    t = bev.bev_to_ground(np.column_stack([np.zeros(bh - v0), np.arange(v0, bh)]))[:, 1] - bev.y_range_m[0]
    shift = (bb[:, None] * t[None, :] + (0.5 * kk)[:, None] * (t * t)[None, :]) * bev.px_per_m[0]
    x0 = shift[:, vs - v0]
    np.subtract(us[None, :], x0, out=x0)
    cols = np.rint(x0, out=x0).astype(np.int64)
    cols += bw * np.arange(len(bb))[:, None]  # each hypothesis its own bins
    inside = (x0 >= 0) & (x0 < bw)
    hist = np.bincount(cols[inside], minlength=len(bb) * bw).reshape(len(bb), bw)
    j = int(np.argmax(np.einsum("ij,ij->i", hist, hist)))  # the sharpest: the largest sum of squares
    return float(bb[j]), float(kk[j]), hist[j].astype(np.float64)


@lru_cache(maxsize=8)
def _shape_grid(shear_max: float, bend_max: float) -> tuple[np.ndarray, np.ndarray]:
    """The (slope, bend) hypotheses _shape tries, flattened: 11 slopes x 7 bends (one value each
    where the limit is 0)."""
    bs = np.linspace(-shear_max, shear_max, 11) if shear_max > 0 else np.zeros(1)
    ks = np.linspace(-bend_max, bend_max, 7) if bend_max > 0 else np.zeros(1)
    bb, kk = (a.ravel() for a in np.meshgrid(bs, ks))
    bb.setflags(write=False)
    kk.setflags(write=False)
    return bb, kk


def _climb(px: _Pixels, valid: np.ndarray, bev: BirdsEye, p: SlidingWindowParams, predict) -> _Line | None:
    """Sliding windows up one line, bottom to top. `predict(v)` is the expected column at row v;
    a window with enough pixels re-centres the prediction on their mean (median) column."""
    bw, bh = bev.size
    win_w = max(2.0, p.window_m * bev.px_per_m[0])
    win_h = max(1, bh // max(1, p.n_windows))
    minpix = max(1, round(p.min_fill * win_w * win_h))
    shift, kept, tried = 0.0, [], 0
    n = max(1, p.n_windows)
    v_his = bh - win_h * np.arange(n)
    v_los = np.maximum(0, v_his - win_h)
    # each window's rows are a slice of the pixels (rows ascending): all the bounds in one search
    bounds = np.searchsorted(px.vs, np.concatenate([v_los, v_his])).tolist()
    for k, (v_lo, v_hi) in enumerate(zip(v_los.tolist(), v_his.tolist())):
        v_mid = 0.5 * (v_lo + v_hi)
        u_c = predict(v_mid) + shift
        lo, hi = bounds[k], bounds[n + k]
        tried += int(0 <= u_c < bw and valid[min(bh - 1, int(v_mid)), int(u_c)] > 0)
        if hi - lo < minpix:  # too few lit pixels in the window's rows to count
            continue
        sel = lo + (np.abs(px.us[lo:hi] - u_c) < win_w / 2).nonzero()[0]
        if len(sel) >= minpix:
            kept.append(sel)
            shift = (order_stats.median(px.us[sel]) if p.median else float(np.mean(px.us[sel]))) - predict(v_mid)
    if not kept:
        return None
    return _line(px, np.concatenate(kept), min(1.0, len(kept) / max(tried, 1)), p)


def _window_search(px: _Pixels, valid: np.ndarray, bev: BirdsEye, p: SlidingWindowParams, lane_width_m: float):
    """(left _Line | None, right _Line | None, kind) from histogram bases and sliding windows."""
    bw, bh = bev.size
    sx, sy = bev.px_per_m
    if not p.pair_bases:  # the report: argmax of each half of the bottom half's histogram
        hist = np.bincount(px.us[px.vs >= bh // 2], minlength=bw)
        bases = [float(np.argmax(hist[: bw // 2])), float(bw // 2 + np.argmax(hist[bw // 2:]))]
        left, right = (_climb(px, valid, bev, p, lambda v, b=b: b) for b in bases)
        return left, right, "pair"
    b, k, hist = _shape(px, bev, p)

    def along_shape(col: int):
        return lambda v: col + (b * (bh - v) / sy + 0.5 * k * ((bh - v) / sy) ** 2) * sx

    lines = [_climb(px, valid, bev, p, along_shape(c)) for c in histogram_peaks(hist, max(1.0, 0.1 * sx))]
    lines = [ln for ln in lines if ln is not None and len(ln.idx) >= p.min_support
             and (plausible(ln.fit, 1) or plausible(ln.fit, -1))]
    xs = [float(ln.fit.x_at(0.0)) for ln in lines]

    def ok(i: int, j: int) -> bool:  # a pair (or a whole two-lane road) keeps its width
        return parallel(lines[i].fit, lines[j].fit, lane_width_m, 2.0 if xs[j] - xs[i] > 1.6 * lane_width_m else 1.0)

    pick = pick_ego_pair(xs, [ln.fill for ln in lines], lane_width_m, ok)
    if pick is None:
        return None, None, "none"
    il, ir, kind = pick
    return (None if il is None else lines[il]), (None if ir is None else lines[ir]), kind


def _search_around(px: _Pixels, bev: BirdsEye, state: SlidingWindowState, p: SlidingWindowParams):
    """(left _Line | None, right _Line | None): the pixels within margin_m of the previous fits."""
    out = []
    for prev in (state.left, state.right):
        idx = np.zeros(0, np.int64)
        if prev is not None:
            idx = np.flatnonzero(np.abs(px.ground[:, 0] - prev.x_at(px.ground[:, 1])) < p.margin_m)
        # how much of the depth the line covers stands in for the windows' fill
        bands = np.floor((px.ground[idx, 1] - bev.y_range_m[0]) / (bev.y_range_m[1] - bev.y_range_m[0]) * p.n_windows)
        line = _line(px, idx, len(np.unique(bands)) / max(p.n_windows, 1), p)
        out.append(line if line.fit is not None and len(idx) >= p.min_support else None)
    return out[0], out[1]


def _boundaries(left: _Line | None, right: _Line | None, kind: str, p: SlidingWindowParams):
    """(left Boundary | None, right Boundary | None, confidence 0..1) from the chosen lines."""
    lb = left.fit if left is not None else None
    rb = right.fit if right is not None else None
    if p.validate:
        # a two-lane road's far edge is seen far off to the side: any pitch error scales its
        # position, so the ego lane is placed from the right line and the lane width instead
        lb = lb if kind != "wide" and plausible(lb, -1) else None
        rb = rb if plausible(rb, +1) else None
        if lb is not None and rb is not None:
            if parallel(lb, rb, p.lane_width_m):
                lb, rb = parallel_fits(left.pts, right.pts) or (lb, rb)
            elif len(left.idx) * left.fill < len(right.idx) * right.fill:
                lb = None
            else:
                rb = None
    fills = [min(1.0, ln.fill / p.full_fill) if ln is not None and b is not None else 0.0
             for ln, b in ((left, lb), (right, rb))]
    if lb is not None and rb is not None:
        return lb, rb, 0.5 * (fills[0] + fills[1])
    return lb, rb, 0.6 * max(fills)  # one line: the other side is a lane-width guess
