"""A camera the user does not have to measure: horizon, pitch and height from the frames.

Lines painted along a road (and its edges) are parallel on the ground, so in the image they meet
at one vanishing point on the horizon. Per frame: straight edge segments (Canny + probabilistic
Hough) sloping the way road lines do, a RANSAC intersection of one rising and one falling segment
scored by the length of every segment that points at it (the point lies ahead of them, above),
then a least-squares refinement on those inliers. Over frames the median vanishing row is the
horizon, robust to frames where a car, a shadow or a bend pulled one frame's point away.

From the horizon row v_h and a focal length f: pitch = atan((cy - v_h) / f) (roll taken as 0).
The lines' sideways spread fixes the camera's height: in a camera 1 m up the two lines that
bound the ego lane lie w1 metres apart; a real lane of `lane_width_m` then puts the camera
lane_width_m / w1 up (the lane methods assume that width, so the views they build stay metric).
Where no frame shows both lines, the nearer one is taken as half a lane away (the car centred).

The field of view is not estimated: for a straight road every line through the vanishing point
reads the same at any focal length (x / y on the ground is fixed, the depth scale is not), so it
is the configured one (an explicit `camera.hfov_deg` is what a user knows from the camera's
data sheet). A wrong field of view scales distances ahead, not the lateral offset.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import cv2
import numpy as np

from signlane.camera import Camera
from signlane.config import CameraConfig

WORK_WIDTH = 480  # frames are scaled to this width for the line search (speed, and fixed thresholds)
MIN_ANGLE_DEG, MAX_ANGLE_DEG = 12.0, 80.0  # road lines in the image: neither flat nor upright
INLIER_DEG = 1.5  # a segment points at the vanishing point within this angle
TOP_K = 14  # RANSAC pairs the longest this many segments of each slope
CLUSTER_H1 = 0.12  # segments this close sideways (in a camera 1 m up) are one line
HEIGHT_RANGE_M = (0.15, 6.0)
# an estimate this close to the configured camera's horizon (fraction of the frame height) says
# the frames come from the configured camera: it is kept exactly
AGREE_FRACTION = 0.04


@dataclass(frozen=True)
class FrameVanishing:
    """One frame's vanishing point (frame pixels)."""

    point: tuple[float, float]
    support: float  # inlier segment length / frame width


@dataclass(frozen=True)
class CameraEstimate:
    """What the frames say about the camera. hfov_deg is the assumed one (see the module doc)."""

    horizon_row: float  # pixels from the top of the frame (may lie outside it)
    pitch_deg: float
    height_m: float | None  # None: no frame showed an ego line
    hfov_deg: float
    frames: int  # frames whose vanishing point was found
    of_frames: int
    vanishing_x: float
    horizon_spread_px: float  # median absolute deviation of the per-frame rows

    def apply(self, camera: Camera) -> Camera:
        """The camera with the estimated pitch (and height, where measured); its size and field
        of view kept."""
        cam = replace(camera, pitch_deg=self.pitch_deg, roll_deg=0.0)
        return replace(cam, height_m=self.height_m) if self.height_m is not None else cam

    def agrees_with(self, camera: Camera) -> bool:
        """The configured camera puts its horizon where the frames do."""
        return abs(horizon_row(camera) - self.horizon_row) <= AGREE_FRACTION * camera.height

    def describe(self) -> str:
        h = f"{self.height_m:.2f} m" if self.height_m is not None else "not measured"
        return (f"horizon row {self.horizon_row:.0f} (+-{self.horizon_spread_px:.0f} px), pitch "
                f"{self.pitch_deg:+.1f} deg, height {h}, hfov {self.hfov_deg:.1f} deg (assumed), "
                f"from {self.frames}/{self.of_frames} frames")


def horizon_row(camera: Camera) -> float:
    """Image row of the horizon at the centre column (roll 0: the whole row)."""
    return camera.height / 2.0 - camera.focal_px * math.tan(math.radians(camera.pitch_deg))


def road_segments(image_bgr: np.ndarray) -> np.ndarray:
    """uint8 BGR or grey (H, W[, 3]) -> float64 (N, 4) segments x1, y1, x2, y2 in frame pixels,
    each sloping 12..80 degrees from the horizontal (what lines along a road look like)."""
    gray = image_bgr if image_bgr.ndim == 2 else cv2.cvtColor(image_bgr, cv2.COLOR_BGR2GRAY)
    h, w = gray.shape
    k = WORK_WIDTH / w
    small = cv2.resize(gray, (WORK_WIDTH, max(8, round(h * k))), interpolation=cv2.INTER_AREA)
    small = cv2.GaussianBlur(small, (5, 5), 0)
    # thresholds from the frame's own contrast: a dim or foggy frame still gives its lines
    gx = cv2.Sobel(small, cv2.CV_32F, 1, 0)
    gy = cv2.Sobel(small, cv2.CV_32F, 0, 1)
    hi = max(30.0, float(np.percentile(np.abs(gx) + np.abs(gy), 90)))
    edges = cv2.Canny(small, hi * 0.4, hi)
    lines = cv2.HoughLinesP(edges, 1, math.pi / 180, threshold=25, minLineLength=WORK_WIDTH * 0.04,
                            maxLineGap=WORK_WIDTH * 0.012)
    if lines is None:
        return np.zeros((0, 4))
    seg = lines.reshape(-1, 4).astype(np.float64) / k
    ang = np.degrees(np.arctan2(np.abs(seg[:, 3] - seg[:, 1]), np.abs(seg[:, 2] - seg[:, 0])))
    return seg[(ang >= MIN_ANGLE_DEG) & (ang <= MAX_ANGLE_DEG)]


def _homogeneous(seg: np.ndarray) -> np.ndarray:
    """(N, 4) segments -> (N, 3) lines a x + b y + c = 0 with (a, b) of unit length."""
    p = np.column_stack([seg[:, 0:2], np.ones(len(seg))])
    q = np.column_stack([seg[:, 2:4], np.ones(len(seg))])
    lines = np.cross(p, q)
    return lines / np.maximum(np.hypot(lines[:, 0], lines[:, 1]), 1e-9)[:, None]


def _inliers(seg: np.ndarray, vp: np.ndarray) -> np.ndarray:
    """Segments whose direction points at vp within INLIER_DEG, with vp above their middle."""
    mid = (seg[:, 0:2] + seg[:, 2:4]) / 2
    d = seg[:, 2:4] - seg[:, 0:2]
    to = vp[None, :] - mid
    cos = np.abs(np.sum(d * to, axis=1)) / np.maximum(np.hypot(*d.T) * np.hypot(*to.T), 1e-9)
    return (cos >= math.cos(math.radians(INLIER_DEG))) & (to[:, 1] < 0)


def vanishing_point(seg: np.ndarray, width: int) -> tuple[np.ndarray, np.ndarray] | None:
    """(vanishing point (2,) frame pixels, inlier mask) of one frame's segments, or None when
    no rising and falling segments meet ahead of enough line length."""
    if len(seg) < 2:
        return None
    length = np.hypot(seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1])
    rising = (seg[:, 2] - seg[:, 0]) * (seg[:, 3] - seg[:, 1]) < 0  # '/' in image coordinates
    a = np.nonzero(rising)[0]
    b = np.nonzero(~rising)[0]
    if len(a) == 0 or len(b) == 0:
        return None
    a = a[np.argsort(-length[a])][:TOP_K]
    b = b[np.argsort(-length[b])][:TOP_K]
    lines = _homogeneous(seg)
    best, best_score = None, 0.0
    for i in a:
        cand = np.cross(lines[i], lines[b])
        ok = np.abs(cand[:, 2]) > 1e-9
        for v in cand[ok, :2] / cand[ok, 2:3]:
            inl = _inliers(seg, v)
            if not (inl & rising).any() or not (inl & ~rising).any():
                continue
            score = float(length[inl].sum())
            if score > best_score:
                best, best_score = v, score
    if best is None or best_score < 0.15 * width:
        return None
    inl = _inliers(seg, best)
    # least squares: the point closest (length-weighted) to every inlier line
    A = lines[inl, :2] * length[inl, None]
    rhs = -lines[inl, 2] * length[inl]
    refined, *_ = np.linalg.lstsq(A, rhs, rcond=None)
    if np.all(np.isfinite(refined)) and np.hypot(*(refined - best)) < 0.1 * width:
        best = refined
    return best, _inliers(seg, best)


def frame_vanishing(image_bgr: np.ndarray) -> tuple[FrameVanishing | None, np.ndarray]:
    """One frame's vanishing point and its inlier segments ((M, 4) frame pixels)."""
    seg = road_segments(image_bgr)
    w = image_bgr.shape[1]
    found = vanishing_point(seg, w)
    if found is None:
        return None, np.zeros((0, 4))
    vp, inl = found
    length = np.hypot(seg[inl, 2] - seg[inl, 0], seg[inl, 3] - seg[inl, 1])
    return FrameVanishing((float(vp[0]), float(vp[1])), float(length.sum() / w)), seg[inl]


def ego_lines_h1(camera_h1: Camera, vp_x: float, segments: np.ndarray) -> tuple[float | None, float | None]:
    """Sideways distances (>= 0) to the nearest line left and right of the camera (None: no
    line on that side), in a camera 1 m up (camera_h1), for segments running towards the
    vanishing point at column vp_x on the camera's horizon."""
    if len(segments) == 0:
        return None, None
    # the road's direction on the ground: the ray through the vanishing point
    ray = np.linalg.inv(camera_h1.K) @ np.array([vp_x, horizon_row(camera_h1), 1.0])
    g = camera_h1.R.T @ ray
    d = np.array([g[0], g[1]]) / max(math.hypot(g[0], g[1]), 1e-9)
    if d[1] <= 0:
        return None, None
    length = np.hypot(segments[:, 2] - segments[:, 0], segments[:, 3] - segments[:, 1])
    # the segment's nearer end (lower in the frame) back-projects most reliably
    low = np.where((segments[:, 1] > segments[:, 3])[:, None], segments[:, 0:2], segments[:, 2:4])
    ground = camera_h1.image_to_ground(low)
    ok = np.all(np.isfinite(ground), axis=1)
    if not ok.any():
        return None, None
    x = ground[ok, 0] * d[1] - ground[ok, 1] * d[0]  # signed distance across the road, + right
    length = length[ok]
    left = _nearest_line(-x[x < 0], length[x < 0], camera_h1.width)
    right = _nearest_line(x[x > 0], length[x > 0], camera_h1.width)
    return left, right


def _nearest_line(dist: np.ndarray, length: np.ndarray, width: int) -> float | None:
    """The nearest sideways distance (>= 0) that enough segment length gathers at."""
    if len(dist) == 0:
        return None
    order = np.argsort(dist)
    dist, length = dist[order], length[order]
    start = 0
    for i in range(1, len(dist) + 1):
        if i == len(dist) or dist[i] - dist[i - 1] > CLUSTER_H1:
            if length[start:i].sum() >= 0.04 * width:  # one near dash of a dashed line
                return float(np.average(dist[start:i], weights=length[start:i]))
            start = i
    return None


def estimate_camera(frames_bgr: list[np.ndarray], camera: Camera, lane_width_m: float = 3.2
                    ) -> CameraEstimate | None:
    """The camera that the frames (one stream, one size) were taken with, or None when no frame
    shows lines meeting at a vanishing point. `camera` gives the size and field of view."""
    if not frames_bgr:
        return None
    h, w = frames_bgr[0].shape[:2]
    camera = camera.with_size(w, h)
    found = [frame_vanishing(f) for f in frames_bgr if f.shape[:2] == (h, w)]
    found = [(fv, s) for fv, s in found if fv is not None]
    if not found:
        return None
    rows = np.array([fv.point[1] for fv, _ in found])
    cols = np.array([fv.point[0] for fv, _ in found])
    row = float(np.median(rows))
    spread = float(np.median(np.abs(rows - row)))
    pitch = math.degrees(math.atan2(h / 2.0 - row, camera.focal_px))
    cam_h1 = replace(camera, height_m=1.0, pitch_deg=pitch, roll_deg=0.0, yaw_deg=0.0)
    sides = [ego_lines_h1(cam_h1, fv.point[0], s) for fv, s in found]
    widths = [a + b for a, b in sides if a is not None and b is not None and a + b > 0]
    if not widths:  # only one line seen in every frame: take the car as centred in its lane
        widths = [2 * (a if a is not None else b) for a, b in sides if (a or b)]
    height = None
    if widths:
        height = float(np.clip(lane_width_m / float(np.median(widths)), *HEIGHT_RANGE_M))
    return CameraEstimate(row, pitch, height, camera.hfov_deg, len(found), len(frames_bgr),
                          float(np.median(cols)), spread)


@dataclass(frozen=True)
class CameraChoice:
    """The camera a stream is read with, and why."""

    camera: CameraConfig
    estimate: CameraEstimate | None
    used: bool  # the estimate replaced the configured pitch and height

    def describe(self) -> str:
        if self.estimate is None:
            return "configured (no road lines meeting at a vanishing point)"
        if not self.used:
            return f"configured (the frames agree: {self.estimate.describe()})"
        return f"estimated: {self.estimate.describe()}"

    def to_dict(self) -> dict:
        c = self.camera
        return {"hfov_deg": round(c.hfov_deg, 2), "height_m": round(c.height_m, 3), "pitch_deg": round(c.pitch_deg, 2),
                "roll_deg": round(c.roll_deg, 2), "estimated": self.used}


def choose_camera(frames_bgr: list[np.ndarray], configured: CameraConfig,
                  lane_width_m: float = 3.2) -> CameraChoice:
    """The configured camera where the frames agree with its horizon (our own simulator's
    frames) or show no vanishing point; otherwise the configured one with the frames' pitch and
    height (the field of view and the mounting ahead of the axle kept). The horizon is the test
    because it is what the frames measure best: the height depends on the lane width assumed
    (VIA's 4 m carriageway reads 20% low). So a camera whose horizon falls where the configured
    one's does is taken for it, whatever its height and field of view."""
    if not frames_bgr:
        return CameraChoice(configured, None, False)
    h, w = frames_bgr[0].shape[:2]
    base = configured.camera(w, h)
    est = estimate_camera(frames_bgr, base, lane_width_m)
    if est is None or est.agrees_with(base):
        return CameraChoice(configured, est, False)
    cam = replace(configured, pitch_deg=round(est.pitch_deg, 3), roll_deg=0.0,
                  height_m=round(est.height_m, 3) if est.height_m is not None else configured.height_m)
    return CameraChoice(cam, est, True)
