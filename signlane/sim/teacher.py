"""The teacher's drives for the pilot ("learn from the teacher", S3): the classical driver drives
the simulator while every frame is recorded with its own command as the label.

A student that only ever saw the teacher on the lane centre has never seen how to come back to
it. `SteeringNoise` perturbs the applied steering on purpose (smooth pulses, as DAVE-2's
recordings shifted the view): the car drifts off the centre, the teacher's perception sees it and
its label says how to steer back, while the label itself stays the teacher's clean command.
Noise pauses through planned junctions and while the car is slow, where a push would only
teach a crash into the kerb the teacher never makes.

DAgger: a student (a driver configured with a pilot model) steers the car instead, so the
recording holds the places the student's own mistakes lead to, each labelled with what the
teacher (the planner and lane follower in the same stack, which still sees every frame) would
have sent. Where the two disagree by more than a takeover margin, the teacher drives for a
moment (`Takeover`): the car stays near the lane, so the teacher's labels stay ones it can
give (a car already on the verge shows no lane to label from).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from signlane.sim.drive_record import Recorder
from signlane.types import Command


@dataclass(frozen=True)
class NoiseParams:
    scale: float = 0.0  # peak steering added, [-scale, scale]; 0 = no perturbation
    gap_s: float = 2.0  # mean time between pulses
    min_s: float = 0.4  # pulse length range
    max_s: float = 1.2
    min_speed: float = 1.0  # m/s: slower than this, no pulse starts


class SteeringNoise:
    """Half-sine steering pulses at random times, seeded: `step(t, state, speed)` -> the
    steering to add this frame."""

    def __init__(self, params: NoiseParams, seed: int):
        self.p = params
        self.rng = np.random.default_rng([int(seed), 7919])
        self._pulse: tuple[float, float, float] | None = None  # (start, length, amplitude)
        self._last_t: float | None = None

    def step(self, t: float, state: str, speed: float) -> float:
        p = self.p
        dt = 0.0 if self._last_t is None else max(t - self._last_t, 0.0)
        self._last_t = t
        if p.scale <= 0 or state.startswith("junction-") or state.startswith("stop"):
            self._pulse = None
            return 0.0
        if self._pulse is None:
            if speed < p.min_speed or self.rng.random() >= dt / p.gap_s:
                return 0.0
            self._pulse = (t, float(self.rng.uniform(p.min_s, p.max_s)), float(self.rng.uniform(-1, 1) * p.scale))
        start, length, amp = self._pulse
        u = (t - start) / length
        if u >= 1.0:
            self._pulse = None
            return 0.0
        return amp * math.sin(math.pi * u)


@dataclass(frozen=True)
class TakeoverParams:
    margin: float = 0.25  # the teacher takes the wheel when the student's steering is this far from its own ...
    hold_s: float = 1.0  # ... and keeps it this long after the last such frame


class Takeover:
    """Who steers a DAgger frame: the student, unless it strays from the teacher by more than
    the margin; then the teacher, until hold_s after the last straying frame."""

    def __init__(self, params: TakeoverParams):
        self.p = params
        self._until = -math.inf
        self.frames = self.taken = 0

    def teacher_steers(self, t: float, student: float, teacher: float) -> bool:
        self.frames += 1
        if abs(student - teacher) > self.p.margin:
            self._until = t + self.p.hold_s
        taken = t < self._until
        self.taken += taken
        return taken


class TeacherRecorder:
    """A Driver that records each frame it drives (every `every`-th) into `recorder`, with the
    teacher's command as the label and the perturbed one applied; steps like the Driver it wraps.
    With a driver that has a pilot (the student), the student's steering is applied where
    `takeover` lets it (DAgger), the teacher's (the stack's planner_command) otherwise."""

    def __init__(self, driver, recorder: Recorder, noise: SteeringNoise | None = None, every: int = 1,
                 takeover: Takeover | None = None):
        self.driver, self.recorder, self.noise = driver, recorder, noise
        self.every = max(1, int(every))
        self.frames = 0
        self.student = getattr(driver, "pilot", None) is not None
        self.takeover = takeover or (Takeover(TakeoverParams()) if self.student else None)

    def step(self, telemetry, now: float | None = None):
        perception, sent = self.driver.step(telemetry, now)
        t = now if now is not None else perception.frame.t
        teacher = self.driver.planner_command if self.student else sent
        extra = {}
        steering = teacher.steering
        if self.student:
            by_teacher = self.takeover.teacher_steers(t, sent.steering, teacher.steering)
            steering = teacher.steering if by_teacher else sent.steering
            extra = {"student": round(float(sent.steering), 4), "steered_by": "teacher" if by_teacher else "student"}
        add = self.noise.step(t, teacher.state, telemetry.speed_mps) if self.noise is not None else 0.0
        applied = Command(float(np.clip(steering + add, -1.0, 1.0)), float(np.clip(teacher.throttle, 0, 1)),
                          teacher.state)
        if self.frames % self.every == 0:
            frame_id = f"{self.frames:06d}"
            self.recorder.write(frame_id, 0, telemetry.jpeg, telemetry, perception, applied,
                                Command(float(np.clip(teacher.steering, -1, 1)), applied.throttle, teacher.state),
                                {"noise": round(float(add), 4), **extra})
        self.frames += 1
        return perception, applied

    def close(self) -> None:
        self.driver.close()

    def __getattr__(self, name):  # behaviour, perception, ...: the wrapped driver's
        return getattr(self.driver, name)

    def __enter__(self) -> "TeacherRecorder":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
