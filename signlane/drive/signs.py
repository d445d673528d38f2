"""The sign stage as the drive stack uses it: in step with each frame, or in a worker thread on
the newest frame (real time); failures as one-line SignStageErrors; confirmed signs placed in
the odometry frame."""
from __future__ import annotations

import math
import threading

import numpy as np

from signlane.odometry import OdoPose
from signlane.types import SignDetection


def sign_positions(confirmed: list[SignDetection], found: tuple[SignDetection, ...], camera, pose: OdoPose,
                   size_m: float, min_aspect: float = 0.0, max_lateral_m: float = float("inf")
                   ) -> list[tuple[str, np.ndarray]]:
    """This frame's detections of confirmed labels, placed in the odometry frame: distance from
    the face height in pixels, bearing from the box centre. Not this car's: a face much narrower
    than it is tall (width < min_aspect x height: turned to another road's traffic) or one
    standing more than max_lateral_m to the side (beside another road). A box cut by the frame's
    edge places nothing: the part in view of an octagon or disc is shorter than the face, which
    would put the sign metres too far."""
    labels = {d.label for d in confirmed}
    out = []
    for d in found:
        if d.label not in labels or d.box[3] < 4 or d.box[2] < min_aspect * d.box[3]:
            continue
        if d.box[0] <= 1 or d.box[1] <= 1 or d.box[0] + d.box[2] >= camera.width - 1 or d.box[1] + d.box[3] >= camera.height - 1:
            continue
        x, y, w, h = d.box
        dist = camera.focal_px * size_m / h
        bearing = math.atan2(x + w / 2 - camera.width / 2, camera.focal_px)
        car = np.array([[dist * math.sin(bearing), dist * math.cos(bearing)]])
        if abs(car[0, 0]) > max_lateral_m:
            continue
        out.append((d.label, pose.to_world(car)[0]))
    return out


class SignStageError(RuntimeError):
    """The sign stage failed on a frame: the frame gets the safe answer; the stage is tried again
    on the next one (str(e) is one line)."""


def stage_failure(e: Exception) -> SignStageError:
    first = (str(e).strip().splitlines() or [""])[0]
    return SignStageError(f"sign stage failed: {type(e).__name__}" + (f": {first}" if first else ""))


class SignWorker:
    """Runs the sign stage on the newest submitted frame in a thread; never blocks the caller.
    A failure is kept until the stage next succeeds: `latest()` raises it meanwhile, so the car
    never drives on as though there were no signs."""

    def __init__(self, stage):
        self.stage = stage
        self._lock = threading.Lock()
        self._job = None
        self._result: tuple = ((), [], None)
        self._error: SignStageError | None = None
        self._wake = threading.Event()
        self._stop = False
        self._thread = threading.Thread(target=self._run, daemon=True, name="signs")
        self._thread.start()

    def submit(self, image: np.ndarray, pose: OdoPose) -> None:
        with self._lock:
            self._job = (image, pose)  # a newer frame replaces one not yet taken
        self._wake.set()

    def latest(self) -> tuple:
        with self._lock:
            if self._error is not None:
                raise self._error
            result, self._result = self._result, ((), self._result[1], None)
        return result  # each result is used once; the confirmed list stays

    def _run(self) -> None:
        while not self._stop:
            self._wake.wait(0.2)
            self._wake.clear()
            with self._lock:
                job, self._job = self._job, None
            if job is None:
                continue
            try:
                found, confirmed = self.stage.step(job[0])
                with self._lock:
                    self._result, self._error = (found, list(confirmed), job[1]), None
                self.stage.settle()  # the band check (signs/face_rows.py), after the result is out
            except Exception as e:  # reported to the driving thread; the next frame tries again
                with self._lock:
                    self._error = stage_failure(e)

    def close(self) -> None:
        self._stop = True
        self._wake.set()
        self._thread.join(timeout=2.0)
