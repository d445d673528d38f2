"""Steering from a LaneEstimate: the source controllers and a pure-pursuit default.

Each controller is a small stateful class with `step(lane, speed) -> steering` (in [-1, 1],
positive right) and `reset()`. `make_controller(name)` builds one by name:

- `s1-proportional`: S1's rule, steering = 0.01 * (lane centre - image centre) in S1's
  bird's-eye pixels, measured here in metres and converted with that view's scale.
- `s3-atan`: S3's rule, angle = atan(x_offset / y_offset) from the lane lines in the image,
  steering = angle / 45 deg.
- `s3-smoothed`: S3's rule with its per-frame rate limit (5 deg with two lines, 3 deg with one)
  and the +-35 deg clamp.
- `pure-pursuit` (default): a lookahead point on the lane centre rebuilt from offset, heading
  and curvature; bicycle-model steering towards it, scaled by the 25 deg maximum wheel angle.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from signlane.camera import Camera
from signlane.types import LaneEstimate

MAX_WHEEL_DEG = 25.0  # VIA scales steering 1.0 to this wheel angle
DEFAULT_LANE_WIDTH_M = 3.2


def _clip(v: float) -> float:
    return float(np.clip(v, -1.0, 1.0))


def lane_width(lane: LaneEstimate) -> float:
    return lane.lane_width_m if lane.lane_width_m > 0 else DEFAULT_LANE_WIDTH_M


def centre_x_at(lane: LaneEstimate, y_m: float) -> float:
    """Lateral position (m, + = right of the car) of the lane centre y_m ahead, rebuilt from
    offset, heading and curvature (x = c + b*y + a*y^2)."""
    c = -lane.offset * lane_width(lane)
    b = -math.tan(lane.heading)
    a = lane.curvature / 2.0 * (1 + b * b) ** 1.5
    return c + b * y_m + a * y_m * y_m


def path_point(path_m: np.ndarray | None, dist_m: float, min_m: float = 3.0) -> tuple[float, float] | None:
    """The first point of a traced centre line (N,2 ground metres) at least dist_m from the car,
    or its last point when it is shorter (and still min_m away); None without a usable path."""
    if path_m is None or len(path_m) < 2:
        return None
    d = np.hypot(path_m[:, 0], path_m[:, 1])
    far = np.flatnonzero(d >= dist_m)
    i = int(far[0]) if len(far) else len(path_m) - 1
    if d[i] < min_m:
        return None
    return float(path_m[i, 0]), float(path_m[i, 1])


def path_bend(path_m: np.ndarray | None, within_m: float) -> float:
    """path_curvature with its sign (+ = the traced centre line bends right): the circle to the
    point within within_m that needs the sharpest one."""
    if path_m is None or len(path_m) < 2:
        return 0.0
    d2 = path_m[:, 0] ** 2 + path_m[:, 1] ** 2
    sel = np.flatnonzero((d2 <= within_m ** 2) & (d2 > 4.0))
    if not len(sel):
        return 0.0
    k = 2 * path_m[sel, 0] / d2[sel]
    return float(k[np.argmax(np.abs(k))])


def path_bend_towards(path_m: np.ndarray | None, within_m: float, side: float) -> float:
    """The sharpest bend toward one side (side +1: right, -1: left) the car would need to reach
    a point of the traced centre line within within_m (1/m, 0 when none bends that way). Unlike
    path_bend it sees a bend beyond an S: the near part of the line bending the other way (the
    end of a lane shift) does not hide it."""
    if path_m is None or len(path_m) < 2:
        return 0.0
    d2 = path_m[:, 0] ** 2 + path_m[:, 1] ** 2
    sel = (d2 <= within_m ** 2) & (d2 > 4.0)
    if not sel.any():
        return 0.0
    return max(0.0, float(np.max(side * 2 * path_m[sel, 0] / d2[sel])))


def path_curvature(path_m: np.ndarray | None, within_m: float) -> float:
    """The sharpest bend (1/m, unsigned) the car would need to reach any point of a traced centre
    line within within_m: 2|x| / (x^2 + y^2), the pure-pursuit circle to that point."""
    return abs(path_bend(path_m, within_m))


class PurePursuit:
    """Steer the bicycle model towards the lane centre `lookahead` metres ahead. Targets are in
    the camera's ground frame; the bicycle turns about its rear axle, `camera_forward_m` behind
    the camera (aimed from the camera instead, the car steers too hard: about 1.5 times on VIA's
    car at a 5 m lookahead, and cuts every bend).

    The point ld ahead on a bend of radius R lies about ld^2 / 2R to the side of the car's
    heading: with a long lookahead the car aims across a bend, and where the bend changes
    direction (an S) or the line traced far into it is off, it runs inside (2 m inside an 18 m
    painted bend at 7.25 m). With `max_cut_m` set, ld is shortened in a bend (the lane's fitted
    curvature) so that ld^2 / 2R stays within it, down to `min_lookahead_m`."""

    def __init__(self, wheelbase_m: float = 1.8, lookahead_m: float = 5.0, lookahead_per_mps: float = 0.5,
                 max_wheel_deg: float = MAX_WHEEL_DEG, camera_forward_m: float = 0.0,
                 max_cut_m: float | None = None, min_lookahead_m: float = 3.0):
        self.wheelbase = wheelbase_m
        self.camera_forward = camera_forward_m
        self.lookahead = lookahead_m
        self.per_mps = lookahead_per_mps
        self.max_cut_m = max_cut_m
        self.min_lookahead = min_lookahead_m
        self.max_wheel = math.radians(max_wheel_deg)
        self.last = 0.0

    def lookahead_m(self, speed: float, curvature: float = 0.0) -> float:
        ld = self.lookahead + self.per_mps * max(speed, 0.0)
        if self.max_cut_m is not None and abs(curvature) > 1e-6:
            ld = min(ld, max(self.min_lookahead, math.sqrt(2.0 * self.max_cut_m / abs(curvature))))
        return ld

    def step(self, lane: LaneEstimate, speed: float = 0.0) -> float:
        if not lane.found:
            self.last *= 0.8  # drift back to straight while the lane is lost
            return self.last
        ld = self.lookahead_m(speed, lane.curvature)
        target = path_point(lane.path_m, ld)
        self.last = self.steer_to(*target) if target is not None else self.steer_to(centre_x_at(lane, ld), ld)
        return self.last

    def steer_to(self, x_m: float, y_m: float) -> float:
        """Steering onto the circle through the rear axle and a target point (x right, y ahead of
        the camera, metres)."""
        y_m += self.camera_forward
        kappa = 2.0 * x_m / max(x_m * x_m + y_m * y_m, 1e-6)
        return _clip(math.atan(self.wheelbase * kappa) / self.max_wheel)

    def reset(self) -> None:
        self.last = 0.0


class S1Proportional:
    """S1: steering = 0.01 * (centre - image centre) in S1's bird's-eye pixels, at its scan row."""

    GAIN_PER_PX = 0.01

    def __init__(self, camera: Camera | None = None):
        self.camera = camera or Camera(640, 480)
        self.px_per_m, self.scan_y_m = _s1_scale(self.camera)

    def step(self, lane: LaneEstimate, speed: float = 0.0) -> float:
        if not lane.found:
            return 0.0
        return _clip(self.GAIN_PER_PX * self.px_per_m * centre_x_at(lane, self.scan_y_m))

    def reset(self) -> None:
        pass


def _s1_scale(camera: Camera) -> tuple[float, float]:
    """S1's bird's-eye maps the bottom image row to W/4 pixels: its px/m there, and the ground
    distance of its scan row (0.9 of the view height, near the bottom)."""
    w, h = camera.width, camera.height
    ends = camera.image_to_ground(np.array([[0.0, h - 1.0], [w - 1.0, h - 1.0]]))
    width_m = float(np.hypot(*(ends[1] - ends[0]))) if np.all(np.isfinite(ends)) else 3.0
    return (w / 4.0) / max(width_m, 1e-3), float(np.nanmean(ends[:, 1])) if np.all(np.isfinite(ends)) else 2.0


class S3Atan:
    """S3: angle = atan(x_offset / y_offset) in image pixels; steering = angle / 45 deg."""

    def __init__(self, camera: Camera | None = None):
        self.camera = camera
        self.last_lines = 0

    def angle_deg(self, lane: LaneEstimate, width: int, height: int) -> float | None:
        tops = []
        for line in (lane.left, lane.right):
            if line is not None and len(line) >= 2:
                tops.append(line)
        self.last_lines = len(tops)
        if not lane.found or not tops:
            return None
        if len(tops) == 2:
            x_top = [float(np.interp(height / 2, l[::-1, 1], l[::-1, 0])) for l in tops]
            x_off, y_off = np.mean(x_top) - width / 2, height / 2
        else:
            line = tops[0]
            x_off, y_off = float(line[-1, 0] - line[0, 0]), float(line[0, 1] - line[-1, 1])
        return math.degrees(math.atan2(x_off, max(y_off, 1e-6)))

    def step(self, lane: LaneEstimate, speed: float = 0.0) -> float:
        cam = self.camera or Camera()
        a = self.angle_deg(lane, cam.width, cam.height)
        return 0.0 if a is None else _clip(a / 45.0)

    def reset(self) -> None:
        self.last_lines = 0


class S3Smoothed(S3Atan):
    """S3 with its rate limit: at most 5 deg change a frame with two lines, 3 with one; +-35 deg."""

    def __init__(self, camera: Camera | None = None):
        super().__init__(camera)
        self.angle = 0.0

    def step(self, lane: LaneEstimate, speed: float = 0.0) -> float:
        cam = self.camera or Camera()
        a = self.angle_deg(lane, cam.width, cam.height)
        if a is not None:
            limit = 5.0 if self.last_lines == 2 else 3.0
            self.angle = float(np.clip(self.angle + np.clip(a - self.angle, -limit, limit), -35.0, 35.0))
        return _clip(self.angle / 45.0)

    def reset(self) -> None:
        super().reset()
        self.angle = 0.0


CONTROLLERS = {"pure-pursuit": PurePursuit, "s1-proportional": S1Proportional, "s3-atan": S3Atan,
               "s3-smoothed": S3Smoothed}


def make_controller(name: str = "pure-pursuit", camera: Camera | None = None):
    if name not in CONTROLLERS:
        raise ValueError(f"unknown controller {name!r}; choose one of {', '.join(CONTROLLERS)}")
    cls = CONTROLLERS[name]
    return cls() if cls is PurePursuit else cls(camera)


@dataclass(frozen=True)
class ThrottlePolicy:
    """Throttle for `infer` on images and video (no odometry there): cruise while the lane is seen,
    else coast. Closed-loop driving uses the sign-aware state machine in signlane/behaviour.py."""

    cruise: float = 0.5

    def throttle(self, lane: LaneEstimate) -> tuple[float, str]:
        return (self.cruise, "cruise") if lane.found else (0.0, "lost")
