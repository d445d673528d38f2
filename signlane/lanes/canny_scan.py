"""S1 `canny-scan`: Canny edges, a bird's-eye view, rows scanned outwards from the car.

Published (VIA "Hello VIA" lane filter, `CannyScanParams.published()`): gray, Gaussian 11x11,
Canny 150/200, the edge image warped to a bird's-eye view, ONE scan row at 0.9 of its height
scanned from the centre column outwards; the first edge pixel on each side is that side's
boundary (straight ahead), a lone side gets the other one lane width away. The source's
hand-picked trapezoid (bottom edge, row 0.4*H) is rebuilt from the camera model.

Robust (the defaults): a metric bird's-eye of the gray image; a marking is a run along a scan row
that is brighter than the road on both sides (horizontal top-hat, relative to the road's own
brightness, so shadows cancel), as wide as paint and bounded by Canny edges; shadow edges and the
road's border are no markings. Many rows keep every such run, and `ego_lane` (shared with
color-hough) turns these marking points into the ego lane's boundaries.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np

from signlane.camera import BirdsEye, Camera
from signlane.lanes import register
from signlane.lanes.association import LaneWidthState, ego_lane
from signlane.lanes.geometry import (DEFAULT_LANE_WIDTH_M, Boundary, camera_for, estimate_from_fits,
                                     fit_boundary)
from signlane.types import LaneEstimate

NAME = "canny-scan"
DOUBLE_GAP_M = 0.3  # strokes closer than this along a row are one (double) line


@dataclass(frozen=True)
class CannyScanParams:
    mode: str = "rows"  # "rows" (robust: many rows, voting) | "single-row" (published)
    blur_px: int = 3  # Gaussian kernel (odd pixels)
    canny_low: float = 30.0
    canny_high: float = 60.0
    lane_width_m: float = DEFAULT_LANE_WIDTH_M  # prior; a lone side gets the other this far away
    # published bird's-eye / scan row
    top_row_frac: float = 0.4  # image row mapped to the bird's-eye top
    scan_row_frac: float = 0.9  # the one scan row, as a fraction of the bird's-eye height
    # robust bird's-eye and its scan rows
    bev_half_width_m: float = 8.0
    bev_px_per_m: float = 20.0
    scan_rows: int = 36
    max_row_step_m: float = 0.4  # farthest row: one image row (per 1/240 of the height) spans this
    max_range_m: float = 25.0
    # what a marking run looks like
    line_width_m: tuple[float, float] = (0.04, 0.8)
    min_contrast: float = 0.2  # brighter than the road beside it by this fraction
    min_contrast_abs: float = 15.0  # ... and by this many gray levels (texture, noise)
    # association
    gate_m: float = 0.3
    min_votes: int = 4

    @classmethod
    def published(cls) -> "CannyScanParams":
        return cls(mode="single-row", blur_px=11, canny_low=150.0, canny_high=200.0)


CannyScanState = LaneWidthState  # the lane width carried between frames


@register(NAME, CannyScanParams)
def canny_scan(image_bgr: np.ndarray, camera: Camera | None, params: CannyScanParams,
               state: CannyScanState | None) -> tuple[LaneEstimate, CannyScanState]:
    """Lane from a uint8 (H, W, 3) BGR image (gray (H, W) is accepted too)."""
    cam = camera_for(image_bgr, camera)
    state = state or CannyScanState()
    gray = to_gray(image_bgr)
    if params.mode == "single-row":
        return _published(gray, cam, params), state
    if params.mode != "rows":
        raise ValueError(f"{NAME}: mode must be 'rows' or 'single-row', not {params.mode!r}")
    return _robust(gray, cam, params, state)


def to_gray(image: np.ndarray) -> np.ndarray:
    """uint8 BGR (H, W, 3), BGRA or gray (H, W) -> uint8 gray (H, W)."""
    img = np.asarray(image)
    if img.dtype != np.uint8:
        img = np.clip(img, 0, 255).astype(np.uint8)
    if img.ndim == 2:
        return img
    if img.shape[2] == 1:
        return img[:, :, 0]
    return cv2.cvtColor(np.ascontiguousarray(img[:, :, :3]), cv2.COLOR_BGR2GRAY)


# --- published ----------------------------------------------------------------------------------
def horizon_row(cam: Camera) -> float:
    """Image row of the horizon at the centre column (may be negative: above the frame)."""
    n, c = cam.horizon()
    if abs(n[1]) < 1e-12:
        return -math.inf
    return float(-(c + n[0] * cam.width / 2.0) / n[1])


@lru_cache(maxsize=16)
def published_birdseye(cam: Camera, top_row_frac: float = 0.4) -> BirdsEye:
    """The source's bird's-eye (W x H) rebuilt from the camera model.

    Rows: the bottom image edge -> bird's-eye bottom, the image row top_row_frac*H (or, when that
    is not safely below the horizon, 5% of the height below it) -> bird's-eye top. The source
    maps the bottom edge to W/4 pixels and the upper row to 1.5*W; one metric view cannot match
    both for every camera, so its scale is the geometric mean of the two.
    """
    W, H = cam.width, cam.height
    top = min(max(top_row_frac * H, horizon_row(cam) + 0.05 * H), H - 2.0)
    g = cam.image_to_ground(np.array([[0, H], [W, H], [0, top], [W, top]], np.float64))
    y0, y1 = float((g[0, 1] + g[1, 1]) / 2), float((g[2, 1] + g[3, 1]) / 2)
    span_b, span_t = abs(g[1, 0] - g[0, 0]), abs(g[3, 0] - g[2, 0])
    px_per_m = math.sqrt((W / 4.0) / max(span_b, 1e-6) * (1.5 * W) / max(span_t, 1e-6))
    half = W / 2.0 / px_per_m
    return cam.birdseye((W, H), (-half, half), (y0, max(y1, y0 + 1.0)))


def _published(gray: np.ndarray, cam: Camera, p: CannyScanParams) -> LaneEstimate:
    k = p.blur_px | 1
    edges = cv2.Canny(cv2.GaussianBlur(gray, (k, k), 0), p.canny_low, p.canny_high)
    bev = published_birdseye(cam, p.top_row_frac)
    Wb, Hb = bev.size
    row = min(int(p.scan_row_frac * Hb), Hb - 1)
    line = bev.warp(edges)[row]
    centre = Wb // 2
    left_hits = centre - 1 - np.flatnonzero(line[:centre][::-1])  # scanning outwards from the centre
    right_hits = centre + np.flatnonzero(line[centre:])
    fits = []
    for hits in (left_hits, right_hits):
        if len(hits) == 0:
            fits.append(None)
            continue
        pt = bev.bev_to_ground(np.array([[hits[0], row]], np.float64))
        # one point: a constant-x (straight ahead) boundary, as the source steers from one row
        fits.append(fit_boundary(pt, order=0, min_points=1, min_span_m=0.0))
    return estimate_from_fits(NAME, cam, fits[0], fits[1], p.lane_width_m, debug_mask=edges)


# --- robust: bird's-eye and scan rows ----------------------------------------------------------------
@dataclass(frozen=True)
class ScanGeometry:
    bev: BirdsEye
    rows: np.ndarray  # bird's-eye row index of each scan row, near to far
    ys: np.ndarray  # ground distance (m) of each scan row
    valid: np.ndarray  # (Hb, Wb) bool: bird's-eye pixels that see the image, away from its border
    x_of_col: np.ndarray  # ground x (m) of each bird's-eye column (OpenCV: pixel index = coordinate)


def ground_range(cam: Camera, max_row_step_m: float = 0.4, max_range_m: float = 25.0) -> tuple[float, float]:
    """(near, far) ground distance in metres worth scanning for this camera.

    Near: the bottom image row, or where the image is about a lane wide if that is farther.
    Far: where one image row (per 1/240 of the height, so resolution-free) spans max_row_step_m
    of ground; beyond, paint is a few pixels and pitch errors dominate.
    """
    H = cam.height
    v = np.arange(H - 1, -1, -1, dtype=np.float64)
    y = cam.image_to_ground(np.column_stack([np.full(H, cam.width / 2.0), v]))[:, 1]
    y = y[np.isfinite(y) & (y > 0)]
    if len(y) < 2:
        return 1.0, 5.0
    near = max(float(y[0]), 1.2 / math.tan(math.radians(cam.hfov_deg) / 2.0))
    coarse = np.flatnonzero(np.diff(y) * (H / 240.0) > max_row_step_m)
    far = float(y[coarse[0]]) if len(coarse) else float(y[-1])
    return near, float(np.clip(far, near + 4.0, near + max_range_m))


@lru_cache(maxsize=16)
def scan_geometry(cam: Camera, p: CannyScanParams) -> ScanGeometry:
    """The metric bird's-eye over ground_range and its scan rows (every 4th bird's-eye row: the
    finer rows only serve the debug mask)."""
    y_near, y_far = ground_range(cam, p.max_row_step_m, p.max_range_m)
    n_rows = p.scan_rows * 4
    w = int(round(2 * p.bev_half_width_m * p.bev_px_per_m))
    bev = cam.birdseye((w, n_rows), (-p.bev_half_width_m, p.bev_half_width_m), (y_near, y_far))
    rows = np.arange(n_rows - 2, 0, -4)  # near (bottom) to far (top)
    ys = bev.bev_to_ground(np.column_stack([np.zeros(len(rows)), rows]))[:, 1]
    inside = bev.visible()
    # the image border is a bright/black step in the bird's-eye: keep the top-hat off it
    kernel = cv2.getStructuringElement(cv2.MORPH_RECT, (_tophat_width(p) + 2, 1))
    valid = cv2.erode(inside, kernel, borderType=cv2.BORDER_CONSTANT, borderValue=0) > 0
    x_of_col = bev.bev_to_ground(np.column_stack([np.arange(w), np.zeros(w)]))[:, 0]
    return ScanGeometry(bev, rows, ys, valid, x_of_col)


def _tophat_width(p: CannyScanParams) -> int:
    """Top-hat kernel (px): wider than the widest paint (a double line), so paint stands out."""
    return int(round(p.line_width_m[1] * 1.25 * p.bev_px_per_m)) | 1


# --- robust: marking runs ------------------------------------------------------------------------------
def marking_mask(bev_gray: np.ndarray, geo: ScanGeometry, p: CannyScanParams) -> np.ndarray:
    """uint8 (Hb, Wb) bird's-eye gray -> bool (Hb, Wb) paint-like pixels: brighter than the road
    to both sides by a fraction of its brightness (shadows and exposure cancel)."""
    k = cv2.getStructuringElement(cv2.MORPH_RECT, (_tophat_width(p), 1))
    opened = cv2.morphologyEx(bev_gray, cv2.MORPH_OPEN, k)
    tophat = cv2.subtract(bev_gray, opened).astype(np.float32)
    thr = np.maximum(p.min_contrast * opened.astype(np.float32), p.min_contrast_abs)
    return (tophat > thr) & geo.valid


def row_runs(mask_rows: np.ndarray, edge_rows: np.ndarray, px_per_m: float,
             p: CannyScanParams) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Runs of paint along each scan row, as wide as paint, with a Canny edge at an end.

    mask_rows, edge_rows: (R, Wb) bool. Returns (row index, start col, end col (exclusive)).
    """
    R, Wb = mask_rows.shape
    pad = np.zeros((R, 1), np.int8)
    d = np.diff(np.concatenate([pad, mask_rows.astype(np.int8), pad], axis=1), axis=1)
    rs, starts = np.nonzero(d == 1)
    _, ends = np.nonzero(d == -1)  # row-major order pairs each start with its end
    width_m = (ends - starts) / px_per_m
    keep = (width_m >= p.line_width_m[0]) & (width_m <= p.line_width_m[1])
    rs, starts, ends = rs[keep], starts[keep], ends[keep]
    cs = np.concatenate([np.zeros((R, 1), np.int32), np.cumsum(edge_rows, axis=1, dtype=np.int32)], axis=1)
    edged = cs[rs, np.clip(ends + 2, 0, Wb)] - cs[rs, np.clip(starts - 2, 0, Wb)] > 0
    return _merge_doubles(rs[edged], starts[edged], ends[edged], px_per_m, p.line_width_m[1])


def _merge_doubles(rs: np.ndarray, starts: np.ndarray, ends: np.ndarray, px_per_m: float,
                   max_width_m: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The two strokes of a double line (a small gap apart) become one marking at their middle:
    otherwise a fit between them is close to neither."""
    if len(rs) < 2:
        return rs, starts, ends
    gap = (starts[1:] - ends[:-1]) / px_per_m
    joined = (rs[1:] == rs[:-1]) & (gap < DOUBLE_GAP_M) & ((ends[1:] - starts[:-1]) / px_per_m <= max_width_m)
    first = np.flatnonzero(np.concatenate([[True], ~joined]))
    last = np.concatenate([first[1:] - 1, [len(rs) - 1]])
    return rs[first], starts[first], ends[last]


# --- robust: the method ------------------------------------------------------------------------------
def _robust(gray: np.ndarray, cam: Camera, p: CannyScanParams,
            state: CannyScanState) -> tuple[LaneEstimate, CannyScanState]:
    geo = scan_geometry(cam, p)
    k = p.blur_px | 1
    bev_gray = geo.bev.warp(cv2.GaussianBlur(gray, (k, k), 0) if k > 1 else gray)
    paint = marking_mask(bev_gray, geo, p)
    edges = cv2.Canny(bev_gray, p.canny_low, p.canny_high) > 0
    px_per_m = geo.bev.px_per_m[0]
    r, s0, s1 = row_runs(paint[geo.rows], edges[geo.rows], px_per_m, p)
    pts = np.column_stack([geo.x_of_col[0] + (s0 + s1 - 1) / 2.0 / px_per_m, geo.ys[r]])  # run middles
    lane = ego_lane(pts, r, len(geo.rows), state.lane_width_m or p.lane_width_m, p.gate_m, p.min_votes,
                    p.bev_half_width_m)
    mask = _debug_mask(paint, geo, lane.seen, p.gate_m)
    if lane.left is None and lane.right is None:
        return LaneEstimate(NAME, False, confidence=0.0, debug_mask=mask), state
    if lane.measured:
        w = lane.width_m if state.lane_width_m is None else 0.8 * state.lane_width_m + 0.2 * lane.width_m
        state = CannyScanState(w)
    return estimate_from_fits(NAME, cam, lane.left, lane.right, lane.width_m, lane.confidence, mask), state


def _debug_mask(paint: np.ndarray, geo: ScanGeometry, fits: list[Boundary], gate_m: float) -> np.ndarray:
    """uint8 0/255 (H, W) mask of the camera image: the paint pixels on the boundaries seen."""
    cam = geo.bev.camera
    keep = np.zeros_like(paint)
    if fits:
        rows = np.arange(paint.shape[0], dtype=np.float64)
        ys = geo.bev.bev_to_ground(np.column_stack([np.zeros(len(rows)), rows]))[:, 1]
        for b in fits:
            keep |= np.abs(geo.x_of_col[None, :] - b.x_at(ys)[:, None]) < gate_m
    bev_mask = (paint & keep).astype(np.uint8) * 255
    return cv2.warpPerspective(bev_mask, geo.bev.bev_to_image_h(), (cam.width, cam.height), flags=cv2.INTER_NEAREST)
