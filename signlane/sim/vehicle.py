"""The simulated car: VIA's car (VIA.md section 2) on a kinematic bicycle.

Physics runs in fixed 50 Hz ticks; `step(dt)` carries what is left of dt over to the next call,
so a 30 frames/s frame is one or two ticks. A reply (`command(steering, throttle)`) takes effect
at the first tick after it arrives, and only then is it evaluated:
  - wheels: steering clamped to [-1, 1] x 25 degrees, set at once (no rate limit, no Ackermann;
    positive = right);
  - pedal: 0.5 if speed / 30 mph < throttle, else 0. Throttle is thus a target fraction of the
    30 mph top speed, held bang-bang at half pedal; with no new reply the pedal stays as it was,
    so the car can pass its target.
Drive force: pedal x 250 N m on each of 4 wheels (radii 0.335 m front, 0.37 m rear), ramped in
from 0 over about 1 s after the first command by traction control; mass 1000 kg; capped at
30 mph. No brake, no reverse: with the pedal at 0 the car coasts under Unity's rigid-body drag
and a constant rolling deceleration, and stops below 0.05 m/s. The pose is the rear axle's.
"""
from __future__ import annotations

from dataclasses import dataclass

from signlane.camera import VIA_WHEELBASE_M
from signlane.odometry import bicycle_step
from signlane.sim.protocol import MPS_PER_MPH
from signlane.world.route import Pose


@dataclass(frozen=True)
class VehicleParams:
    """VIA's car (CarRemoteControl.cs, CarController.cs, Car.prefab), except `rolling_decel_mps2`."""

    wheelbase_m: float = VIA_WHEELBASE_M
    max_wheel_deg: float = 25.0
    max_speed: float = 30.0 * MPS_PER_MPH  # 13.41 m/s: the cap, and what throttle is a fraction of
    pedal_on: float = 0.5  # the pedal VIA applies while below the target speed
    torque_nm: float = 250.0  # per wheel at full pedal, 4 driven wheels
    wheel_radius_front_m: float = 0.335
    wheel_radius_rear_m: float = 0.37
    mass_kg: float = 1000.0
    traction_ramp_s: float = 1.0  # traction control brings the torque from 0 to full in about this
    drag: float = 0.1  # Unity rigid-body drag: speed *= 1 - drag * dt every tick
    # Wheel damping and tyre friction while coasting. VIA.md gives no number: this is an estimate
    # (it makes a car coast about 15 m from 5 m/s), not a measurement of VIA.
    rolling_decel_mps2: float = 0.5
    stop_below_mps: float = 0.05  # a coasting car slower than this stops
    physics_hz: float = 50.0

    @property
    def full_accel_mps2(self) -> float:
        """Acceleration at full pedal and full torque, before drag (2.84 m/s^2: half pedal 1.42)."""
        force_n = 2 * self.torque_nm / self.wheel_radius_front_m + 2 * self.torque_nm / self.wheel_radius_rear_m
        return force_n / self.mass_kg


class Vehicle:
    """State: pose (world metres, rear axle, heading CCW from +x), speed (m/s, >= 0), wheel_deg
    (applied wheel angle, + right), pedal (0 or 0.5), odometer_m, ticks (physics steps taken)."""

    def __init__(self, pose: Pose, params: VehicleParams | None = None, speed: float = 0.0):
        self.params = params or VehicleParams()
        self.pose = pose
        self.speed = float(speed)
        self.wheel_deg = 0.0
        self.pedal = 0.0
        self.odometer_m = 0.0
        self.ticks = 0
        self._pending: tuple[float, float] | None = None  # the newest reply not yet applied
        self._carry_s = 0.0  # simulated time not yet stepped (less than one tick)
        self._since_control_s: float | None = None  # physics time since the first command

    def command(self, steering: float, throttle: float) -> None:
        """A reply arrived: it takes effect at the next physics tick (a newer one replaces it)."""
        self._pending = (float(steering), float(throttle))

    def step(self, dt: float) -> None:
        """Advance dt seconds in whole physics ticks, carrying the remainder to the next call."""
        p = self.params
        tick = 1.0 / p.physics_hz
        self._carry_s += max(float(dt), 0.0)
        n = int(self._carry_s / tick + 1e-9)  # the epsilon keeps 3 x (1/30 s) at exactly 5 ticks
        self._carry_s = max(self._carry_s - n * tick, 0.0)
        x, y, th = self.pose.x, self.pose.y, self.pose.heading
        for _ in range(n):
            self._apply_pending()
            self._update_speed(tick)
            x, y, th = bicycle_step(x, y, th, self.speed, self.wheel_deg, p.wheelbase_m, tick)
            self.odometer_m += self.speed * tick
            self.ticks += 1
        self.pose = Pose(x, y, th)

    def _apply_pending(self) -> None:
        if self._pending is None:
            return
        p = self.params
        steering, throttle = self._pending
        self._pending = None
        self.wheel_deg = min(max(steering, -1.0), 1.0) * p.max_wheel_deg
        self.pedal = p.pedal_on if self.speed / p.max_speed < throttle else 0.0
        if self._since_control_s is None:
            self._since_control_s = 0.0

    def _update_speed(self, h: float) -> None:
        p = self.params
        v = self.speed
        if self.pedal > 0.0:
            ramp = min(self._since_control_s / p.traction_ramp_s, 1.0) if p.traction_ramp_s > 0 else 1.0
            v += self.pedal * ramp * p.full_accel_mps2 * h
        v *= 1.0 - p.drag * h
        if self.pedal <= 0.0:
            v -= p.rolling_decel_mps2 * h
            if v < p.stop_below_mps:
                v = 0.0
        self.speed = min(max(v, 0.0), p.max_speed)
        if self._since_control_s is not None:
            self._since_control_s += h
