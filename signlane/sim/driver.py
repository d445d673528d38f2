"""The driver behind the drive server: telemetry in, Command out.

Per frame: odometry from speed and wheel angle; lanes and junction openings on a scaled frame;
signs (proposals, classifier, N-of-M confirmation) on the full frame, placed in the odometry
frame from their box size; then the behaviour state machine (signlane/behaviour.py). One Driver
per connection: it carries tracking, confirmation, odometry and the state machine.

With `sync_signs=False` the sign stage runs in a worker thread beside the lane path on the
newest frame it can take, and steering uses its latest result, so classification never stalls
steering (real time). Synchronous signs make lockstep runs deterministic.
"""
from __future__ import annotations

import math
import threading
import time
from dataclasses import replace

import cv2
import numpy as np

from signlane import lanes
from signlane.behaviour import Behaviour, BehaviourParams
from signlane.config import Config
from signlane.junction import JunctionDetector, view_from_scan, with_road_end
from signlane.lanes.auto import road_state
from signlane.odometry import Odometry, OdoPose
from signlane.sim.protocol import Telemetry
from signlane.types import Command, Frame, Perception, SignDetection


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


def _stage_failure(e: Exception) -> SignStageError:
    first = (str(e).strip().splitlines() or [""])[0]
    return SignStageError(f"sign stage failed: {type(e).__name__}" + (f": {first}" if first else ""))


class _SignWorker:
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
            except Exception as e:  # reported to the driving thread; the next frame tries again
                with self._lock:
                    self._error = _stage_failure(e)
                continue
            with self._lock:
                self._result, self._error = (found, list(confirmed), job[1]), None

    def close(self) -> None:
        self._stop = True
        self._wake.set()
        self._thread.join(timeout=2.0)


class Driver:
    def __init__(self, config: Config | None = None, sync_signs: bool = True):
        self.config = config or Config()
        dc = self.config.drive
        self.sync_signs = sync_signs
        cfg_lanes = self.config.lanes
        lanes.params_for(cfg_lanes.method, cfg_lanes.variant, **cfg_lanes.overrides())  # fail early on a bad name
        self.behaviour = Behaviour(BehaviourParams(
            max_speed=dc.max_speed, cruise_speed=dc.cruise_speed, approach_speed=dc.approach_speed,
            stop_hold_s=dc.stop_hold_s, coast_decel=dc.coast_decel, wheelbase_m=dc.wheelbase_m,
            camera_forward_m=self.config.camera.forward_m))
        self.odometry = Odometry(dc.wheelbase_m)
        self.signs = None
        self._worker = None
        if self.config.signs.enabled:
            from signlane.signs.stage import SignStage
            self.signs = SignStage(self.config.signs)
            if not sync_signs:
                self._worker = _SignWorker(self.signs)
        self._size = None
        self.seq = 0

    def _setup(self, width: int, height: int) -> None:
        if self._size == (width, height):
            return
        cfg = self.config
        lw = cfg.drive.lanes_width
        scale = lw / width if 0 < lw < width else 1.0
        self.scaled = (round(width * scale), round(height * scale))
        self.camera = cfg.camera.camera(width, height)
        small = cfg.camera.camera(*self.scaled)
        self.lane = lanes.get(cfg.lanes.method, camera=small, variant=cfg.lanes.variant, **cfg.lanes.overrides())
        self.junctions = JunctionDetector(small)
        self._size = (width, height)

    def step(self, telemetry: Telemetry, now: float | None = None) -> tuple[Perception, Command]:
        image = telemetry.image_bgr
        h, w = image.shape[:2]
        self._setup(w, h)
        t = telemetry.time if telemetry.time is not None else (time.monotonic() if now is None else now)
        timing: dict[str, float] = {}
        t0 = time.perf_counter()
        # the camera's ground point: what the camera measures (lanes, junctions, signs) is planned from it
        pose = self.odometry.step(t, telemetry.speed_mps, telemetry.wheel_deg).ahead(self.config.camera.forward_m)
        small = image if self.scaled == (w, h) else cv2.resize(image, self.scaled, interpolation=cv2.INTER_AREA)
        lane = self.lane(small)
        t1 = time.perf_counter()
        timing["lanes"] = (t1 - t0) * 1e3
        road = road_state(self.lane.state)
        two_lane = road is None or road.two_lane
        if not two_lane:  # a kerbed carriageway: openings where its edges jump away
            view = view_from_scan(road.scan)
        else:  # painted lanes: openings where the edge line is missing; a road ending ahead from the scan
            view = self.junctions.detect(small, lane.lane_width_m or None)
            if road is not None and road.scan is not None:
                view = with_road_end(view, road.scan)
        t2 = time.perf_counter()
        timing["junction"] = (t2 - t1) * 1e3
        signs = self._signs(image, pose, small)
        t3 = time.perf_counter()
        timing["signs"] = (t3 - t2) * 1e3
        if self.signs is not None and self._worker is None:  # its parts (in the worker: another thread's)
            timing.update({f"signs_{k}": v for k, v in self.signs.last_ms.items()})
        was = self.behaviour.path is not None
        steering, throttle, state = self.behaviour.step(t, pose, self.odometry.distance_m, telemetry.speed_mps,
                                                        lane, view, two_lane)
        if was and self.behaviour.path is None:  # the tracker's last fit is from before the junction
            keep = getattr(self.lane.state, "forget_tracks", None)
            self.lane.state = keep() if keep else None
        timing["control"] = (time.perf_counter() - t3) * 1e3
        if self.scaled != (w, h):  # report the lane in the frame's own pixels
            k = w / self.scaled[0]
            lane = replace(lane, left=None if lane.left is None else lane.left * k,
                           right=None if lane.right is None else lane.right * k)
        frame = Frame(image, t, self.seq)
        self.seq += 1
        return Perception(frame, lane, signs, timing), Command(steering, throttle, state)

    def _signs(self, image: np.ndarray, pose: OdoPose, small: np.ndarray) -> tuple[SignDetection, ...]:
        if self.signs is None:
            return ()
        if self._worker is None:
            try:  # the lane copy is the proposals' half-size frame when it is half the frame's size
                found, confirmed = self.signs.step(image, small)
            except Exception as e:
                raise _stage_failure(e) from e
            at = pose
        else:
            self._worker.submit(image, pose)
            found, confirmed, at = self._worker.latest()
            if at is None:
                return ()
        dc = self.config.drive
        placed = sign_positions(confirmed, found, self.camera, at, dc.sign_size_m, dc.sign_min_aspect,
                                dc.sign_max_lateral_m)
        self.behaviour.observe_signs(placed)
        return tuple(found)

    def reset(self) -> None:
        if self._size is not None:
            self.lane.reset()
            self.junctions.reset()
        self.behaviour.reset()
        self.odometry.reset()
        if self.signs is not None:
            self.signs.reset()
        self.seq = 0

    def close(self) -> None:
        if self._worker is not None:
            self._worker.close()
            self._worker = None

    def __enter__(self) -> "Driver":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
