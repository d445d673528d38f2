"""The driver behind the drive server and the in-process simulator: VIA telemetry in, Command out.

The drive stack itself is transport-free (signlane/drive/stack.py); this is its VIA edge: it
takes a decoded `Telemetry` and the clock the run keeps (the message's simulated `time` when it
has one, else `now`, else the monotonic clock). One Driver per connection.
"""
from __future__ import annotations

import time

from signlane.drive.signs import SignStageError, sign_positions  # noqa: F401  (their home before signlane/drive)
from signlane.drive.stack import DriveStack
from signlane.sim.protocol import Telemetry
from signlane.types import Command, Perception


class Driver(DriveStack):
    def step(self, telemetry: Telemetry, now: float | None = None) -> tuple[Perception, Command]:
        t = telemetry.time if telemetry.time is not None else (time.monotonic() if now is None else now)
        return self.drive(telemetry.image_bgr, telemetry.speed_mps, telemetry.wheel_deg, t)

    def __enter__(self) -> "Driver":
        return self
