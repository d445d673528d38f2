"""Dead reckoning from speed and wheel angle: where the car has gone since a moment ago.

Junctions and stop lines are planned in this frame, because the camera stops seeing what a
plan refers to (markings vanish in a junction; a stop sign leaves the view before the car
stops). Frame: metres, heading radians CCW from +x; starts at the origin facing +y.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class OdoPose:
    x: float = 0.0
    y: float = 0.0
    heading: float = math.pi / 2

    def to_world(self, xy_car: np.ndarray) -> np.ndarray:
        """Points in this pose's car frame (x right, y ahead) -> odometry frame, (N, 2)."""
        p = np.asarray(xy_car, float).reshape(-1, 2)
        fx, fy = math.cos(self.heading), math.sin(self.heading)
        rx, ry = fy, -fx  # right of travel
        return np.column_stack([self.x + p[:, 0] * rx + p[:, 1] * fx, self.y + p[:, 0] * ry + p[:, 1] * fy])

    def ahead(self, dist_m: float) -> "OdoPose":
        """The pose dist_m further along its heading (the camera's ground point, from the axle's)."""
        return OdoPose(self.x + dist_m * math.cos(self.heading), self.y + dist_m * math.sin(self.heading), self.heading)

    def to_car(self, xy: np.ndarray) -> np.ndarray:
        """Odometry-frame points -> this pose's car frame (x right, y ahead), (N, 2)."""
        d = np.asarray(xy, float).reshape(-1, 2) - (self.x, self.y)
        fx, fy = math.cos(self.heading), math.sin(self.heading)
        return np.column_stack([d[:, 0] * fy - d[:, 1] * fx, d[:, 0] * fx + d[:, 1] * fy])


def bicycle_step(x: float, y: float, heading: float, speed: float, wheel_deg: float, wheelbase_m: float,
                 dt: float) -> tuple[float, float, float]:
    """One kinematic-bicycle step of the rear axle (heading CCW, wheel angle + right), with the
    midpoint heading so arcs stay accurate at 20-100 Hz."""
    yaw_rate = -speed / wheelbase_m * math.tan(math.radians(wheel_deg))
    mid = heading + 0.5 * yaw_rate * dt
    return x + speed * dt * math.cos(mid), y + speed * dt * math.sin(mid), heading + yaw_rate * dt


class Odometry:
    """Integrates (speed m/s, wheel angle deg + right) over dt with a bicycle model."""

    def __init__(self, wheelbase_m: float = 1.8):
        self.wheelbase = wheelbase_m
        self.pose = OdoPose()
        self.distance_m = 0.0
        self.t: float | None = None

    def step(self, t: float, speed: float, wheel_deg: float) -> OdoPose:
        dt = 0.0 if self.t is None else min(max(t - self.t, 0.0), 0.5)  # a stall is not a teleport
        self.t = t
        p = self.pose
        self.pose = OdoPose(*bicycle_step(p.x, p.y, p.heading, speed, wheel_deg, self.wheelbase, dt))
        self.distance_m += speed * dt
        return self.pose

    def reset(self) -> None:
        self.__init__(self.wheelbase)
