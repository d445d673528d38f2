"""S3 `color-hough`: colour masks, Canny, probabilistic Hough segments, one line per side.

Published (the Donkey-car OpenCV autopilot, `ColorHoughParams.published()`): HSV masks for the
yellow left line (H 15-45, S>=40, V>=40) and the white right line (S<=30, V>=200); Canny(200,400)
on each; the yellow mask's lower-left quarter and the white mask's lower-right quarter;
HoughLinesP(rho 1, theta 1 deg, threshold 10, minLineLength 8, maxLineGap 8; pixel counts scaled
from the source's 160x120); vertical segments dropped; left keeps negative image slopes, right
positive; the mean (slope, intercept) per side, extended from y=H to y=H/2. Those image lines are
sampled, turned into ground points and fitted.

Robust (the defaults): paint is what is brighter than the road beside it (a horizontal top-hat of
HSV value, its width the metric paint width at that distance, relative to the road's brightness
there, so exposure and shadows cancel) and white or yellow, either colour on either side; the
region is the ground the camera resolves (from the camera model), not image quarters. Each
horizontal run of paint is thinned to its middle pixel (instead of Canny's two outlines) for
HoughLinesP; the segments go to the ground, where those not running along the road are dropped
(and, being clutter, raise the evidence asked of the rest), and are sampled on rows of ground
distance. The side and the lane come from where the lines lie, not their slope sign:
`canny_scan.ego_lane` picks the ego lane's pair (or the far road edge, or one line and the
lane-width prior).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np

from signlane.camera import Camera
from signlane.lanes import register
from signlane.lanes.association import LaneWidthState, ego_lane
from signlane.lanes.canny_scan import ground_range, horizon_row
from signlane.lanes.geometry import (DEFAULT_LANE_WIDTH_M, Boundary, camera_for, estimate_from_fits,
                                     fit_boundary, image_points_to_ground)
from signlane.types import LaneEstimate

NAME = "color-hough"
SOURCE_SIZE = (160, 120)  # the source's frame: Hough pixel counts scale from it


@dataclass(frozen=True)
class ColorHoughParams:
    mode: str = "ground"  # "ground" (robust) | "quarters" (published)
    # published colour masks (OpenCV HSV: H 0-180, S and V 0-255)
    yellow_lo: tuple[int, int, int] = (15, 40, 40)
    yellow_hi: tuple[int, int, int] = (45, 255, 255)
    white_lo: tuple[int, int, int] = (0, 0, 200)
    white_hi: tuple[int, int, int] = (180, 30, 255)
    canny_low: float = 200.0  # (published only)
    canny_high: float = 400.0
    # HoughLinesP at the source's 160x120 (scaled to the image); the source: 10, 8, 8. The robust
    # variant votes with one pixel per row (run centres), so it asks for fewer and bridges more.
    hough_threshold: int = 8
    min_line_length: float = 6.0
    max_line_gap: float = 10.0
    lane_width_m: float = DEFAULT_LANE_WIDTH_M  # prior; a lone side gets the other this far away
    # robust paint test
    paint_width_m: float = 0.8  # top-hat width: wider than the widest paint (a double line)
    min_contrast: float = 0.2  # brighter than the road beside it by this fraction of its value
    min_contrast_abs: float = 15.0  # ... and by this many levels (texture, noise)
    white_s_max: int = 70  # saturation of white paint under a colour cast
    yellow_s_min: int = 70
    max_along_slope: float = 0.7  # |dx/dy| of a ground segment that runs along the road
    rows: int = 36  # rows of ground distance the segments are sampled on
    gate_m: float = 0.3
    min_votes: int = 4

    @classmethod
    def published(cls) -> "ColorHoughParams":
        return cls(mode="quarters", hough_threshold=10, min_line_length=8.0, max_line_gap=8.0)


ColorHoughState = LaneWidthState  # the lane width carried between frames


@register(NAME, ColorHoughParams)
def color_hough(image_bgr: np.ndarray, camera: Camera | None, params: ColorHoughParams,
                state: ColorHoughState | None) -> tuple[LaneEstimate, ColorHoughState]:
    """Lane from a uint8 (H, W, 3) BGR image (gray (H, W) is accepted and treated as colourless)."""
    cam = camera_for(image_bgr, camera)
    state = state or ColorHoughState()
    hsv = to_hsv(image_bgr)
    if params.mode == "quarters":
        return _published(hsv, cam, params), state
    if params.mode != "ground":
        raise ValueError(f"{NAME}: mode must be 'ground' or 'quarters', not {params.mode!r}")
    return _robust(hsv, cam, params, state)


def to_hsv(image: np.ndarray) -> np.ndarray:
    """uint8 BGR (H, W, 3), BGRA or gray (H, W) -> uint8 HSV (H, W, 3), OpenCV ranges."""
    img = np.asarray(image)
    if img.dtype != np.uint8:
        img = np.clip(img, 0, 255).astype(np.uint8)
    if img.ndim == 2 or img.shape[2] == 1:
        img = cv2.cvtColor(img.reshape(img.shape[:2]), cv2.COLOR_GRAY2BGR)
    return cv2.cvtColor(np.ascontiguousarray(img[:, :, :3]), cv2.COLOR_BGR2HSV)


def hough_segments(edges: np.ndarray, p: ColorHoughParams) -> np.ndarray:
    """HoughLinesP on a uint8 (H, W) edge image with the source's pixel counts scaled to it;
    returns (N, 4) float x1, y1, x2, y2 image pixels."""
    h, w = edges.shape
    s = 0.5 * (w / SOURCE_SIZE[0] + h / SOURCE_SIZE[1])
    segs = cv2.HoughLinesP(edges, 1, math.pi / 180, max(1, int(round(p.hough_threshold * s))),
                           minLineLength=p.min_line_length * s, maxLineGap=p.max_line_gap * s)
    return np.zeros((0, 4)) if segs is None else segs.reshape(-1, 4).astype(np.float64)


# --- published --------------------------------------------------------------------------------------
def _published(hsv: np.ndarray, cam: Camera, p: ColorHoughParams) -> LaneEstimate:
    H, W = hsv.shape[:2]
    yellow = cv2.Canny(cv2.inRange(hsv, p.yellow_lo, p.yellow_hi), p.canny_low, p.canny_high)
    white = cv2.Canny(cv2.inRange(hsv, p.white_lo, p.white_hi), p.canny_low, p.canny_high)
    yellow[: H // 2] = 0
    yellow[:, W // 2:] = 0  # lower-left quarter
    white[: H // 2] = 0
    white[:, : W // 2] = 0  # lower-right quarter
    fits = []
    for edges, sign in ((yellow, -1.0), (white, 1.0)):
        line = _mean_line(hough_segments(edges, p), sign)
        fits.append(None if line is None else _image_line_boundary(cam, *line))
    return estimate_from_fits(NAME, cam, fits[0], fits[1], p.lane_width_m, debug_mask=yellow | white)


def _mean_line(segs: np.ndarray, sign: float) -> tuple[float, float] | None:
    """Mean (slope, intercept) of the image segments whose slope has the given sign."""
    x1, y1, x2, y2 = segs.T
    ok = x1 != x2  # vertical: no slope
    slope = (y2[ok] - y1[ok]) / (x2[ok] - x1[ok])
    icpt = y1[ok] - slope * x1[ok]
    keep = slope * sign > 0
    if not keep.any():
        return None
    return float(slope[keep].mean()), float(icpt[keep].mean())


def _image_line_boundary(cam: Camera, slope: float, icpt: float) -> Boundary | None:
    """The image line y = slope*x + icpt from y=H up to y=H/2 (kept below the horizon) as a
    straight ground boundary."""
    H = cam.height
    top = max(H / 2.0, horizon_row(cam) + 0.05 * H)
    ys = np.linspace(H, top, 12)
    g = image_points_to_ground(cam, np.column_stack([(ys - icpt) / slope, ys]))
    return fit_boundary(g, order=1, min_points=2, min_span_m=0.3)


# --- robust: where to look ----------------------------------------------------------------------------
@dataclass(frozen=True)
class RoiGeometry:
    top: int  # first image row of the region (ground up to the far distance)
    bands: tuple[tuple[int, int, int], ...]  # (row0, row1, top-hat kernel px): wider kernels nearer
    ys: np.ndarray  # ground distances of the sampling rows (m), near to far


@lru_cache(maxsize=16)
def roi_geometry(cam: Camera, paint_width_m: float, n_rows: int) -> RoiGeometry:
    """Region, top-hat bands and sampling rows for a camera, from its model (cached)."""
    W, H = cam.width, cam.height
    near, far = ground_range(cam)
    v_far = float(cam.ground_to_image(np.array([[0.0, far]]))[0, 1])
    top = int(np.clip(math.floor(v_far), 0, H - 1)) if math.isfinite(v_far) else H
    bands = []
    v1 = H
    while v1 > top:
        # paint width in pixels at the band's nearest row; the band ends where that halves
        y1 = float(cam.image_to_ground(np.array([[W / 2.0, v1 - 1.0]]))[0, 1])
        if not (math.isfinite(y1) and y1 > 0):
            break  # (a tiny or odd image: that row does not see the ground)
        kpx = _px_per_m(cam, y1) * paint_width_m
        v0 = float(cam.ground_to_image(np.array([[0.0, min(2.0 * y1, far)]]))[0, 1])
        v0 = int(np.clip(math.floor(v0), top, v1 - 1)) if math.isfinite(v0) else top
        bands.append((v0, v1, max(3, int(round(kpx)) | 1)))
        v1 = v0
    top = bands[-1][0] if bands else H
    return RoiGeometry(top, tuple(bands), np.linspace(near, far, n_rows))


def _px_per_m(cam: Camera, y: float) -> float:
    """Image pixels per ground metre across the road at distance y straight ahead."""
    a, b = cam.ground_to_image(np.array([[-0.5, y], [0.5, y]]))
    return float(abs(b[0] - a[0]))


def paint_mask(hsv: np.ndarray, roi: RoiGeometry, p: ColorHoughParams) -> np.ndarray:
    """uint8 HSV (H, W, 3) -> uint8 0/255 (H, W): white or yellow pixels brighter than the road
    to both sides, within the region."""
    hue, sat, val = cv2.split(hsv)
    bright = np.zeros(val.shape, bool)
    for v0, v1, k in roi.bands:
        band = val[v0:v1]
        opened = cv2.morphologyEx(band, cv2.MORPH_OPEN, cv2.getStructuringElement(cv2.MORPH_RECT, (k, 1)))
        tophat = cv2.subtract(band, opened).astype(np.float32)
        bright[v0:v1] = tophat > np.maximum(p.min_contrast * opened.astype(np.float32), p.min_contrast_abs)
    white = sat <= p.white_s_max
    yellow = (hue >= p.yellow_lo[0]) & (hue <= p.yellow_hi[0]) & (sat >= p.yellow_s_min)
    return ((bright & (white | yellow)) * 255).astype(np.uint8)


def run_centres(mask: np.ndarray) -> np.ndarray:
    """uint8 0/255 (H, W) -> uint8 0/255 (H, W) with one pixel at the middle of each horizontal
    run: a cheap thinning, so Hough sees each line once (not its two Canny edges) and has 1/10
    of the pixels to vote with."""
    H, W = mask.shape
    pad = np.zeros((H, 1), np.int8)
    d = np.diff(np.concatenate([pad, (mask > 0).astype(np.int8), pad], axis=1), axis=1)
    rs, starts = np.nonzero(d == 1)
    _, ends = np.nonzero(d == -1)
    out = np.zeros_like(mask)
    out[rs, (starts + ends - 1) // 2] = 255
    return out


# --- robust: segments to marking points ------------------------------------------------------------------
def ground_samples(segs: np.ndarray, cam: Camera, ys: np.ndarray,
                   max_slope: float) -> tuple[np.ndarray, np.ndarray, float]:
    """Image segments (N, 4) -> marking points (M, 2) ground metres on the rows `ys` (a segment
    between two rows gives a point on the nearer), their row index (M,), and the clutter: the
    share of segment length (ground) not running along the road (stop lines, shadow edges,
    texture), which is dropped."""
    if len(segs) == 0:
        return np.zeros((0, 2)), np.zeros(0, np.int64), 0.0
    g = cam.image_to_ground(segs.reshape(-1, 2)).reshape(-1, 2, 2)
    g = g[np.all(np.isfinite(g), axis=(1, 2))]
    near_first = g[:, 0, 1] > g[:, 1, 1]
    g[near_first] = g[near_first][:, ::-1]
    (xa, ya), (xb, yb) = g[:, 0].T, g[:, 1].T
    dy = yb - ya
    slope = (xb - xa) / np.maximum(dy, 1e-6)
    keep = (dy > 1e-3) & (np.abs(slope) <= max_slope)
    length = np.hypot(xb - xa, dy)
    clutter = float(length[~keep].sum() / max(float(length.sum()), 1e-9))
    xa, ya, yb, slope = xa[keep], ya[keep], yb[keep], slope[keep]
    step = ys[1] - ys[0]
    inside = (ys[None, :] >= ya[:, None] - 0.5 * step) & (ys[None, :] <= yb[:, None] + 0.5 * step)
    si, ri = np.nonzero(inside)
    x = xa[si] + slope[si] * (ys[ri] - ya[si])
    return np.column_stack([x, ys[ri]]), ri, clutter


def merge_close(pts: np.ndarray, rows: np.ndarray, gap_m: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """Points on one row closer than gap_m become their mean: overlapping segments of one line,
    or the two strokes of a double line, are one marking."""
    if len(pts) < 2:
        return pts, rows
    order = np.lexsort((pts[:, 0], rows))
    pts, rows = pts[order], rows[order]
    new = np.concatenate([[True], (rows[1:] != rows[:-1]) | (np.diff(pts[:, 0]) >= gap_m)])
    starts = np.flatnonzero(new)
    counts = np.diff(np.concatenate([starts, [len(pts)]]))
    return np.add.reduceat(pts, starts, axis=0) / counts[:, None], rows[starts]


# --- robust: the method ----------------------------------------------------------------------------------
def _robust(hsv: np.ndarray, cam: Camera, p: ColorHoughParams,
            state: ColorHoughState) -> tuple[LaneEstimate, ColorHoughState]:
    roi = roi_geometry(cam, p.paint_width_m, p.rows)
    paint = paint_mask(hsv, roi, p)
    paint[: roi.top] = 0
    centres = np.zeros_like(paint)
    centres[roi.top:] = run_centres(paint[roi.top:])
    segs = hough_segments(centres, p)
    pts, rows, clutter = ground_samples(segs, cam, roi.ys, p.max_along_slope)
    pts, rows = merge_close(pts, rows)
    # where most segments cross the road at random, the few along it may be chance too: ask more
    min_votes = int(math.ceil(p.min_votes / math.sqrt(max(1.0 - clutter, 0.02))))
    lane = ego_lane(pts, rows, len(roi.ys), state.lane_width_m or p.lane_width_m, p.gate_m, min_votes)
    mask = _debug_mask(paint, cam, lane.seen, p.gate_m)
    if lane.left is None and lane.right is None:
        return LaneEstimate(NAME, False, confidence=0.0, debug_mask=mask), state
    if lane.measured:
        w = lane.width_m if state.lane_width_m is None else 0.8 * state.lane_width_m + 0.2 * lane.width_m
        state = ColorHoughState(w)
    return estimate_from_fits(NAME, cam, lane.left, lane.right, lane.width_m, lane.confidence, mask), state


def _debug_mask(paint: np.ndarray, cam: Camera, fits: list[Boundary], gate_m: float) -> np.ndarray:
    """uint8 0/255 (H, W): the paint pixels within about gate_m (ground) of a boundary seen."""
    band = np.zeros_like(paint)
    for b in fits:
        ys = np.linspace(max(b.y_range[0], 0.3), b.y_range[1], 16)
        xs = b.x_at(ys)
        c, lo, hi = (cam.ground_to_image(np.column_stack([xs + d, ys])) for d in (0.0, -gate_m, gate_m))
        width = np.linalg.norm(hi - lo, axis=1)
        for k in range(len(ys) - 1):  # a thick segment per step, as wide as the gate there
            p0, p1 = np.round(c[k]).astype(int), np.round(c[k + 1]).astype(int)
            t = int(np.clip(width[k], 1, paint.shape[1] // 2))
            cv2.line(band, (int(p0[0]), int(p0[1])), (int(p1[0]), int(p1[1])), 255, t)
    return cv2.bitwise_and(paint, band)
