"""Bird's-eye marking helpers shared by sliding-window and vector-spline: the view, the
bright-stripe mask, histogram peaks, ego-pair choice and plausibility checks."""
from __future__ import annotations

from collections.abc import Callable
from functools import lru_cache

import cv2
import numpy as np

from signlane.camera import BirdsEye, Camera
from signlane.lanes.geometry import Boundary, curvature_of, fit_boundary


@lru_cache(maxsize=32)
def ego_birdseye(camera: Camera, x_half_m: float, depth_m: float, px_per_m: tuple[float, float] | None,
                 near_row: float = 1.0) -> BirdsEye:
    """Bird's-eye view of the road ahead from the camera model: ground x in +-x_half_m, y from the
    ground seen at `near_row` (fraction of the height, 1 = bottom row) to depth_m beyond it;
    px_per_m None gives a bird's-eye of the camera's own size (as the S2 report did). One view
    per camera and setting, made once: its homographies are then computed once, not every frame."""
    v = min(camera.height - 1.0, near_row * camera.height)
    y0 = float(camera.image_to_ground(np.array([[camera.width / 2.0, v]]))[0, 1])
    if not np.isfinite(y0) or y0 <= 0:
        y0 = 2.0  # the row sees no ground (camera looks up): start a little ahead
    if px_per_m is None:
        size = (camera.width, camera.height)
    else:
        size = (max(8, round(2 * x_half_m * px_per_m[0])), max(8, round(depth_m * px_per_m[1])))
    return camera.birdseye(size, (-x_half_m, x_half_m), (y0, y0 + depth_m))


def visible_mask(bev: BirdsEye) -> np.ndarray:
    """uint8 (h, w) of the bird's-eye, read-only: 255 where the camera sees the ground."""
    return bev.visible()


def ridge_mask(bev_bgr: np.ndarray, valid: np.ndarray, ridge_px: int, rel: float, minimum: float,
               smooth_rows: int = 1, smooth_cols: int = 1, noise_k: float = 0.0) -> np.ndarray:
    """Lane paint in a bird's-eye BGR uint8 (h, w, 3) image -> uint8 (h, w) 0/255 mask.

    Paint is a stripe brighter than the road on *both* sides `ridge_px` columns away; shadow
    borders and road edges are one-sided steps and fail. The threshold is relative to the road's
    brightness (shadows scale both). Brightness adds a yellowness term ((R+G)/2 - B) so yellow
    paint on grey asphalt counts like white. Averaging `smooth_rows` rows favours stripes running
    ahead over texture specks; `smooth_cols` tames noise but dims the thinnest lines. With
    noise_k > 0 a stripe must also rise noise_k times above the road texture's typical contrast.
    """
    b, g, r = (c.astype(np.float32) for c in cv2.split(bev_bgr))
    lum = 0.114 * b + 0.587 * g + 0.299 * r + 0.5 * np.maximum(0.5 * (r + g) - b, 0)
    lum = cv2.blur(lum, (max(1, int(smooth_cols)), max(1, int(smooth_rows))))
    d = max(2, int(ridge_px))
    side_l, side_r = np.full_like(lum, np.inf), np.full_like(lum, np.inf)
    side_l[:, d:], side_r[:, :-d] = lum[:, :-d], lum[:, d:]
    rise = np.minimum(lum - side_l, lum - side_r)
    bg = np.maximum(side_l, side_r)
    floor = minimum
    if noise_k > 0:  # a textured road makes stripes of its own: rise above its typical contrast
        inner = valid[:, d:-d] > 0
        if inner.any():
            dev = np.abs(lum[:, d:-d] - 0.5 * (side_l[:, d:-d] + side_r[:, d:-d]))[inner]
            floor = max(minimum, noise_k * 1.4826 * float(np.median(dev[::4])))
    ok = rise > np.maximum(floor, rel * np.where(np.isfinite(bg), bg, 0))
    # next to the view's border the comparison is with the black outside: not there
    ok &= cv2.erode(valid, np.ones((1, 2 * d + 1), np.uint8)) > 0
    return ok.astype(np.uint8) * 255


def sobel_s_mask(bgr: np.ndarray, sobel_thresh: tuple[int, int], s_thresh: tuple[int, int]) -> np.ndarray:
    """The S2 report's binary of a BGR uint8 image: Sobel-x of HLS lightness scaled to 0..255 in
    sobel_thresh, OR HLS saturation in s_thresh -> uint8 (h, w) 0/255."""
    hls = cv2.cvtColor(bgr, cv2.COLOR_BGR2HLS)
    sx = np.abs(cv2.Sobel(hls[:, :, 1], cv2.CV_32F, 1, 0))
    scaled = (255.0 * sx / max(float(sx.max()), 1e-6)).astype(np.uint8)
    grad = (scaled >= sobel_thresh[0]) & (scaled <= sobel_thresh[1])
    sat = (hls[:, :, 2] >= s_thresh[0]) & (hls[:, :, 2] <= s_thresh[1])
    return (grad | sat).astype(np.uint8) * 255


def histogram_peaks(hist: np.ndarray, smooth_px: float, rel: float = 0.15, top: int = 6) -> list[int]:
    """Columns of the strongest local maxima of a 1-D histogram (smoothed), strongest first."""
    k = max(3, int(2 * round(1.5 * smooth_px) + 1))
    h = cv2.GaussianBlur(hist.astype(np.float32).reshape(1, -1), (k, 1), smooth_px).ravel()
    if h.max() <= 0:
        return []
    ring = np.concatenate([h[-1:], h, h[:1]])  # each column's neighbours, wrapping round (as np.roll)
    idx = ((h >= ring[:-2]) & (h > ring[2:]) & (h >= rel * h.max())).nonzero()[0]
    return [int(i) for i in idx[np.argsort(-h[idx])][:top]]


def pick_ego_pair(xs_m: list[float], strengths: list[float], lane_width_m: float,
                  parallel: Callable[[int, int], bool] | None = None):
    """The ego lane's boundaries among candidate lines (x metres at the car, strength 0..1).

    Returns (left index | None, right index | None, kind) or None; kind is 'pair', 'single', or
    'wide': a two-lane road without a centre line, the car in the right lane, where the left line
    is the road's far edge. The car (x = 0) is inside its lane, which is 0.75..1.4 nominal widths
    wide; `parallel(i, j)` may veto a pair.
    """
    best, best_score = None, 0.0
    lo, hi = 0.75 * lane_width_m, 1.4 * lane_width_m
    for i, xi in enumerate(xs_m):
        for j, xj in enumerate(xs_m):
            w = xj - xi
            if lo <= w <= hi and xi < 0.3 and xj > -0.3:
                score, kind = (strengths[i] + strengths[j]) * (1.0 - 0.5 * abs(w - lane_width_m) / lane_width_m), "pair"
            elif 2 * lo <= w <= 2 * hi and xi + w / 2 < 0.3 and xj > 0.2:
                score, kind = 0.6 * (strengths[i] + strengths[j]), "wide"
            else:
                continue
            if score > best_score and (parallel is None or parallel(i, j)):
                best, best_score = (i, j, kind), score
    for i, x in enumerate(xs_m):  # a lone line is the nearer boundary on its side of the car
        if 0.1 < abs(x) < 0.75 * hi and 0.45 * strengths[i] > best_score:
            best, best_score = ((None, i, "single") if x > 0 else (i, None, "single")), 0.45 * strengths[i]
    return best


def parallel_fits(left_m: np.ndarray, right_m: np.ndarray) -> tuple[Boundary, Boundary] | None:
    """Both boundaries from one shape (lane lines are parallel): a side seen briefly or only far
    away borrows the other's shape instead of extrapolating its own quadratic to the car.
    Points are ground metres (N, 2); returns (left, right) or None."""
    fl, fr = fit_boundary(left_m), fit_boundary(right_m)
    if fl is None or fr is None:
        return None
    half = width_between(fl, fr) / 2
    centre = fit_boundary(np.vstack([left_m + (half, 0.0), right_m - (half, 0.0)]))
    if centre is None:
        return None
    out = []
    for pts, b in ((left_m, fl), (right_m, fr)):
        d = float(np.median(pts[:, 0] - centre.x_at(pts[:, 1])))
        out.append(Boundary(centre.coeffs + (0.0, 0.0, d), b.y_range, b.support))
    return out[0], out[1]


def plausible(b: Boundary | None, side: int) -> bool:
    """A boundary on its side of the car (-1 left, +1 right), bending no tighter than an 8 m
    radius and not running across the view."""
    if b is None:
        return False
    x0 = float(b.x_at(0.0))
    if side * x0 < -0.3 or abs(x0) > 8.0:
        return False
    y_mid = 0.5 * (b.y_range[0] + b.y_range[1])
    return abs(curvature_of(b.coeffs, y_mid)) < 1 / 8.0 and abs(b.coeffs[-2] + 2 * b.coeffs[-3] * y_mid) < 1.5


def parallel(left: Boundary, right: Boundary, nominal_m: float, factor: float = 1.0) -> bool:
    """The boundaries keep a lane's width (times factor) apart over the depth both were seen."""
    y0 = max(left.y_range[0], right.y_range[0])
    ys = np.linspace(y0, max(y0, min(left.y_range[1], right.y_range[1])), 5)
    w = right.x_at(ys) - left.x_at(ys)
    return bool(np.all((w > 0.7 * factor * nominal_m) & (w < 1.45 * factor * nominal_m)))


def width_between(left: Boundary, right: Boundary) -> float:
    """Lane width (m) at the nearest depth both boundaries were seen."""
    y = max(left.y_range[0], right.y_range[0])
    return float(right.x_at(y) - left.x_at(y))


