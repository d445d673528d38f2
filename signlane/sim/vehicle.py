"""The simulated car: a kinematic bicycle with VIA's control semantics.

`steering` in [-1, 1] (positive right) is scaled to the maximum wheel angle (25 degrees) and the
wheels turn towards it at a finite rate; `throttle` in [0, 1] is a target speed fraction: each
physics tick the car accelerates at a fixed rate while speed / max_speed < throttle and coasts
(rolling drag) otherwise, so throttle 0 rolls the car to a stop. The pose is the rear axle's,
which is also where the camera sits.
"""
from __future__ import annotations

from dataclasses import dataclass

from signlane.odometry import bicycle_step
from signlane.world.route import Pose


@dataclass(frozen=True)
class VehicleParams:
    wheelbase_m: float = 1.8
    max_wheel_deg: float = 25.0
    wheel_rate_deg_s: float = 240.0  # how fast the wheels follow the steering command
    max_speed: float = 10.0  # m/s at throttle 1
    accel: float = 3.0  # m/s^2 while below the target speed
    coast_decel: float = 1.5  # m/s^2 rolling drag while coasting (no brakes in VIA)
    physics_hz: float = 100.0


class Vehicle:
    """State: pose (world metres, heading CCW from +x), speed (m/s), wheel angle (deg, + right)."""

    def __init__(self, pose: Pose, params: VehicleParams | None = None, speed: float = 0.0):
        self.params = params or VehicleParams()
        self.pose = pose
        self.speed = float(speed)
        self.wheel_deg = 0.0
        self.throttle = 0.0
        self.odometer_m = 0.0

    def step(self, steering: float, throttle: float, dt: float) -> None:
        """Advance dt seconds with the command held, in fixed physics ticks."""
        p = self.params
        self.throttle = min(max(float(throttle), 0.0), 1.0)
        target_wheel = min(max(float(steering), -1.0), 1.0) * p.max_wheel_deg
        n = max(1, int(round(dt * p.physics_hz)))
        h = dt / n
        x, y, th = self.pose.x, self.pose.y, self.pose.heading
        for _ in range(n):
            dw = target_wheel - self.wheel_deg
            lim = p.wheel_rate_deg_s * h
            self.wheel_deg += min(max(dw, -lim), lim)
            if self.speed / p.max_speed < self.throttle:
                self.speed = min(self.speed + p.accel * h, p.max_speed)
            else:
                self.speed = max(self.speed - p.coast_decel * h, 0.0)
            x, y, th = bicycle_step(x, y, th, self.speed, self.wheel_deg, p.wheelbase_m, h)
            self.odometer_m += self.speed * h
        self.pose = Pose(x, y, th)
