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

    def to_car(self, xy: np.ndarray) -> np.ndarray:
        """Odometry-frame points -> this pose's car frame (x right, y ahead), (N, 2)."""
        d = np.asarray(xy, float).reshape(-1, 2) - (self.x, self.y)
        fx, fy = math.cos(self.heading), math.sin(self.heading)
        return np.column_stack([d[:, 0] * fy - d[:, 1] * fx, d[:, 0] * fx + d[:, 1] * fy])


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
        yaw_rate = -speed / self.wheelbase * math.tan(math.radians(wheel_deg))
        p = self.pose
        mid = p.heading + 0.5 * yaw_rate * dt
        self.pose = OdoPose(p.x + speed * dt * math.cos(mid), p.y + speed * dt * math.sin(mid),
                            p.heading + yaw_rate * dt)
        self.distance_m += speed * dt
        return self.pose

    def reset(self) -> None:
        self.__init__(self.wheelbase)
