"""Lane geometry shared by every lane method: boundary fitting and LaneEstimate assembly.

Methods find boundary points (in image or bird's-eye pixels), convert them to ground metres
(x right, y forward) and call `fit_boundary` and `estimate_from_fits`: the offset, heading,
curvature and image polylines are then computed one way for all methods.

A boundary is the polynomial x(y) = a*y^2 + b*y + c in ground metres (numpy.polyfit order).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from signlane.camera import BirdsEye, Camera
from signlane.types import LaneEstimate

DEFAULT_LANE_WIDTH_M = 3.2
CURVATURE_AT_M = 8.0  # curvature is reported at this distance ahead (the middle of the usual view)
POLYLINE_STEP_M = 0.5


@dataclass(frozen=True)
class Boundary:
    """A fitted boundary: x(y) coefficients (highest power first) valid over y_range metres."""

    coeffs: np.ndarray
    y_range: tuple[float, float]
    support: int = 0  # number of points behind the fit

    def x_at(self, y) -> np.ndarray:
        return polyval(self.coeffs, y)


def polyval(coeffs, x):
    """np.polyval(coeffs, x) for a float or an array x: the same Horner steps in the same order
    (so the same floats), without its conversions, which cost more than a quadratic's arithmetic
    (a lane estimate evaluates a few curves a frame)."""
    y = coeffs[0] * x + coeffs[1] if len(coeffs) > 1 else coeffs[0] + 0.0 * x
    for c in coeffs[2:]:
        y = y * x + c
    return y


def fit_boundary(points_m: np.ndarray, order: int = 2, weights: np.ndarray | None = None,
                 min_points: int = 3, min_span_m: float = 1.0) -> Boundary | None:
    """Least-squares fit of x(y) to ground points (N,2) metres; None when too few or too short.

    The order drops to 1 when the points span too little distance for a stable quadratic.
    """
    pts = np.asarray(points_m, dtype=np.float64).reshape(-1, 2)
    finite = np.all(np.isfinite(pts), axis=1)
    pts = pts[finite]
    if weights is not None:
        weights = np.asarray(weights, dtype=np.float64).reshape(-1)[finite]
    if len(pts) < min_points:
        return None
    y0, y1 = float(pts[:, 1].min()), float(pts[:, 1].max())
    if y1 - y0 < min_span_m:
        return None
    if y1 - y0 < 4.0 or len(pts) < 6:
        order = min(order, 1)
    coeffs = polyfit(pts[:, 1], pts[:, 0], order, weights)
    if len(coeffs) < 3:
        coeffs = np.concatenate([np.zeros(3 - len(coeffs)), coeffs])
    return Boundary(coeffs, (y0, y1), len(pts))


def polyfit(y: np.ndarray, x: np.ndarray, order: int, weights: np.ndarray | None = None) -> np.ndarray:
    """np.polyfit(y, x, order, w=sqrt(weights)) for order 1 or 2: the weighted least-squares
    coefficients, highest power first. Solved from the normal equations of y centred and scaled
    to [-1, 1] (well conditioned for any span of rows), then mapped back to y: the same curve
    to about 1e-13, in half np.polyfit's time (12 against 24 us a call: its SVD and checks; every
    lane method fits several boundaries a frame). A system that is singular (all
    points on fewer distinct rows than coefficients) goes to np.polyfit, as before."""
    if order not in (1, 2):
        return np.polyfit(y, x, order, w=None if weights is None else np.sqrt(weights))
    m = 0.5 * (float(y.min()) + float(y.max()))
    s = max(0.5 * (float(y.max()) - float(y.min())), 1e-9)
    t = (y - m) / s
    v = np.empty((order + 1, len(t)))
    v[order] = 1.0
    v[order - 1] = t
    if order == 2:
        np.multiply(t, t, out=v[0])
    vw = v if weights is None else v * weights
    c = _solve_normal((vw @ v.T).tolist(), (vw @ x).tolist())
    if c is None:
        return np.polyfit(y, x, order, w=None if weights is None else np.sqrt(weights))
    if order == 1:
        return np.array([c[0] / s, c[1] - c[0] * m / s])
    p2, p1, p0 = c[0] / (s * s), c[1] / s, c[2]
    return np.array([p2, p1 - 2.0 * p2 * m, p0 - p1 * m + p2 * m * m])


def _solve_normal(a: list, b: list) -> list | None:
    """The 2x2 or 3x3 symmetric system a c = b by Cramer's rule (scalars: numpy's solve costs
    more than the arithmetic), or None when it is near singular."""
    if len(b) == 2:
        (p, q), (_, r) = a
        det = p * r - q * q
        if not abs(det) > 1e-12 * max(p * r, 1e-300):
            return None
        return [(b[0] * r - q * b[1]) / det, (p * b[1] - q * b[0]) / det]
    (a00, a01, a02), (_, a11, a12), (_, _, a22) = a
    c00 = a11 * a22 - a12 * a12
    c01 = a02 * a12 - a01 * a22
    c02 = a01 * a12 - a02 * a11
    det = a00 * c00 + a01 * c01 + a02 * c02
    if not abs(det) > 1e-12 * max(a00 * a11 * a22, 1e-300):
        return None
    c11 = a00 * a22 - a02 * a02
    c12 = a01 * a02 - a00 * a12
    c22 = a00 * a11 - a01 * a01
    b0, b1, b2 = b
    return [(c00 * b0 + c01 * b1 + c02 * b2) / det, (c01 * b0 + c11 * b1 + c12 * b2) / det,
            (c02 * b0 + c12 * b1 + c22 * b2) / det]


def slant(slope: float) -> float:
    """1 / cos of the angle a curve runs at from straight ahead, from its slope dx/dy: what a
    distance across it becomes measured sideways. Capped at a slope of 2 (63 degrees), beyond
    which a fit's slope says more about its noise than about the road."""
    return math.sqrt(1.0 + min(slope * slope, 4.0))


def shifted(boundary: Boundary, dx_m: float) -> Boundary:
    """The same curve moved sideways by dx_m (right positive): the lane-width fallback.

    A width is measured across the lane, so where the seen curve runs aslant (a bend) the
    sideways shift is the width over the cosine of its angle at its near end."""
    c = boundary.coeffs.copy()
    slope = float(np.polyval(np.polyder(c), boundary.y_range[0])) if len(c) > 1 else 0.0
    c[-1] += dx_m * slant(slope)
    return Boundary(c, boundary.y_range, 0)


def curvature_of(coeffs: np.ndarray, y: float) -> float:
    """Signed curvature (1/m, + = bends right) of x(y) at y."""
    a, b = coeffs[-3], coeffs[-2]
    slope = 2 * a * y + b
    return float(2 * a / (1 + slope * slope) ** 1.5)


def estimate_from_fits(method: str, camera: Camera, left: Boundary | None, right: Boundary | None,
                       lane_width_m: float = DEFAULT_LANE_WIDTH_M, confidence: float | None = None,
                       debug_mask: np.ndarray | None = None) -> LaneEstimate:
    """LaneEstimate from fitted boundaries; a missing side is placed one lane width away."""
    if not lane_width_m > 0:  # a caller's measured width of 0 (or NaN) must not divide
        lane_width_m = DEFAULT_LANE_WIDTH_M
    if left is None and right is None:
        return LaneEstimate(method, False, confidence=0.0, debug_mask=debug_mask)
    if left is None:
        left = shifted(right, -lane_width_m)
    if right is None:
        right = shifted(left, lane_width_m)
    centre = (left.coeffs + right.coeffs) / 2.0
    width = float(right.x_at(0.0) - left.x_at(0.0))
    if not 0.3 * lane_width_m < width < 3.0 * lane_width_m:
        width = lane_width_m  # implausible measured width: use the nominal one for the fraction
    offset = -float(polyval(centre, 0.0)) / width
    heading = -math.atan(float(centre[-2]))
    y_lo = max(0.5, min(left.y_range[0], right.y_range[0]))
    y_hi = max(left.y_range[1], right.y_range[1])
    curvature = curvature_of(centre, float(np.clip(CURVATURE_AT_M, y_lo, y_hi)))
    if confidence is None:
        confidence = 1.0 if (left.support and right.support) else 0.5
    # the fitted centre itself, where it was seen: steering aims at a point on it. Rebuilt from
    # offset and heading at the car and the curvature 8 m ahead instead, a bend's entry (slope
    # near 0 at the car, steep 8 m on) comes out with half its bend and the car runs wide.
    ys = np.arange(y_lo, y_hi + 1e-9, POLYLINE_STEP_M)
    path = np.column_stack([polyval(centre, ys), ys]) if len(ys) >= 2 else None
    return LaneEstimate(method, True, offset=offset, heading=heading, curvature=curvature,
                        confidence=float(confidence), left=boundary_polyline(camera, left, y_lo, y_hi),
                        right=boundary_polyline(camera, right, y_lo, y_hi), debug_mask=debug_mask,
                        lane_width_m=width, path_m=path)


def boundary_polyline(camera: Camera, b: Boundary, y_lo: float, y_hi: float) -> np.ndarray:
    """Image pixels (N,2) of a boundary between y_lo and y_hi metres ahead, inside the frame."""
    ys = np.arange(y_lo, y_hi + 1e-9, POLYLINE_STEP_M)
    if len(ys) < 2:
        ys = np.array([y_lo, y_hi])
    pix = camera.ground_to_image(np.column_stack([b.x_at(ys), ys]))
    keep = (pix[:, 0] >= 0) & (pix[:, 0] <= camera.width - 1) & (pix[:, 1] >= 0) & (pix[:, 1] <= camera.height - 1)
    return pix[keep].astype(np.float32)


def bev_points_to_ground(bev: BirdsEye, uv: np.ndarray) -> np.ndarray:
    """Bird's-eye pixels (N,2) -> ground metres (N,2)."""
    return bev.bev_to_ground(uv)


def image_points_to_ground(camera: Camera, pix: np.ndarray) -> np.ndarray:
    """Image pixels (N,2) -> ground metres (N,2); pixels at or above the horizon are dropped."""
    g = camera.image_to_ground(pix)
    return g[np.all(np.isfinite(g), axis=1)]


def camera_for(image: np.ndarray, camera: Camera | None) -> Camera:
    """The given camera resized to the image, or the default camera at the image's size."""
    h, w = image.shape[:2]
    cam = camera or Camera()
    return cam if (cam.width, cam.height) == (w, h) else cam.with_size(w, h)
