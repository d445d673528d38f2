"""The closed-loop drive stack: one camera frame plus what the car reports (speed, wheel angle,
time) in, Perception and Command out. No sockets, no files: the drive server, the local
simulator and `signlane run` (camera, video) each feed it frames from their own source.

Per frame: odometry from speed and wheel angle; lanes and junction openings on a scaled frame;
signs (proposals, classifier, N-of-M confirmation) on the full frame, placed in the odometry
frame from their box size; then the behaviour state machine (signlane/behaviour.py). One stack
per stream (connection, camera): it carries tracking, confirmation, odometry and the state
machine.

With `sync_signs=False` the sign stage runs in a worker thread on the newest frame it can take,
and steering uses its latest result, so classification never stalls steering (real time). The
worker gets each frame once its command is out (`answered()`, else at the next frame), so its
search fills the gap between frames rather than competing with the steering path for the
interpreter. Synchronous signs make lockstep runs deterministic.

With a pilot (`--set pilot.model=FILE`, signlane/pilot.py) the pilot's steering replaces the
lane follower's; lanes, junctions and signs still run, because the behaviour layer plans speed,
stops and exits from them, and the chosen exit is the pilot's desire. Where the planner has lost
the lane the pilot still steers, and the car keeps `pilot.lost_speed` instead of coasting to a stand.
"""
from __future__ import annotations

import time

import numpy as np

from signlane.behaviour import Behaviour, BehaviourParams
from signlane.config import CameraConfig, Config
from signlane.control import MAX_WHEEL_DEG  # steering 1.0 as a wheel angle, for odometry
from signlane.drive.perception import PerceptionStack
from signlane.drive.signs import sign_positions
from signlane.odometry import Odometry, OdoPose
from signlane.types import Command, Frame, Perception, SignDetection


class ToldCar:
    """What a source that reports no speed or wheel angle (a camera, a recorded video) gives the
    stack for them: the car is taken to do what it was last told, the target speed of the last
    throttle and the wheel angle of the last steering."""

    def __init__(self, max_speed_mps: float):
        self.max_speed = max_speed_mps
        self.speed_mps = self.wheel_deg = 0.0

    def told(self, command: Command) -> None:
        self.speed_mps, self.wheel_deg = command.throttle * self.max_speed, command.steering * MAX_WHEEL_DEG

    def reset(self) -> None:
        self.speed_mps = self.wheel_deg = 0.0


class DriveStack:
    def __init__(self, config: Config | None = None, sync_signs: bool = True):
        self.config = config or Config()
        dc = self.config.drive
        self.sync_signs = sync_signs
        self.perception = PerceptionStack(self.config, dc.lanes_width, sync_signs, after_answer=True, sign_rows=True)
        from signlane.pilot import PilotSteering, from_config
        model = from_config(self.config.pilot)
        self.pilot = PilotSteering(model, self.config.pilot.junctions) if model is not None else None
        self.behaviour = Behaviour(BehaviourParams(
            max_speed=dc.max_speed, cruise_speed=dc.cruise_speed, approach_speed=dc.approach_speed,
            stop_hold_s=dc.stop_hold_s, coast_decel=dc.coast_decel, wheelbase_m=dc.wheelbase_m,
            camera_forward_m=self.config.camera.forward_m,
            # the pilot steers without a lane estimate: with one, a lost lane slows the car to a
            # crawl instead of a stand it would never leave
            lost_speed=self.config.pilot.lost_speed if self.pilot is not None else 0.0))
        self.odometry = Odometry(dc.wheelbase_m)
        self.signs = self.perception.signs
        self.planner_command: Command | None = None  # the last frame's command before the pilot steered
        self.seq = 0

    @property
    def camera(self):
        """The full frame's camera (None before the first frame)."""
        return self.perception.camera

    def drive(self, image: np.ndarray, speed_mps: float, wheel_deg: float, t: float) -> tuple[Perception, Command]:
        """One frame: image uint8 (H, W, 3) BGR; speed m/s; applied wheel angle degrees (+ right);
        t seconds on any steady clock (simulated or monotonic)."""
        ps = self.perception
        h, w = image.shape[:2]
        timing: dict[str, float] = {}
        t0 = time.perf_counter()
        # the camera's ground point: what the camera measures (lanes, junctions, signs) is planned from it
        pose = self.odometry.step(t, speed_mps, wheel_deg).ahead(self.config.camera.forward_m)
        lane, small = ps.lanes_on(image)
        t1 = time.perf_counter()
        timing["lanes"] = (t1 - t0) * 1e3
        view, two_lane = ps.junction_view(small, lane, self.odometry.distance_m)
        t2 = time.perf_counter()
        timing["junction"] = (t2 - t1) * 1e3
        signs = self._signs(image, pose, small)
        t3 = time.perf_counter()
        timing["signs"] = (t3 - t2) * 1e3
        timing.update(ps.sign_ms)
        was = self.behaviour.path is not None
        steering, throttle, state = self.behaviour.step(t, pose, self.odometry.distance_m, speed_mps,
                                                        lane, view, two_lane)
        if was and self.behaviour.path is None:  # the tracker's last fit is from before the junction
            ps.forget_tracks()
        t4 = time.perf_counter()
        timing["control"] = (t4 - t3) * 1e3
        # what the planner itself would send: the label of a drive the pilot steers (DAgger)
        self.planner_command = Command(steering, throttle, state)
        if self.pilot is not None:
            steering = self.pilot.steer(small, state, steering, lane)
            timing["pilot"] = (time.perf_counter() - t4) * 1e3
        lane = ps.in_frame_pixels(lane, w)  # report the lane in the frame's own pixels
        frame = Frame(image, t, self.seq)
        self.seq += 1
        return Perception(frame, lane, signs, timing), Command(steering, throttle, state)

    def answered(self) -> None:
        """The last frame's command has been sent: the work put off until then is done now (if
        never called, with the next frame): the lane method's (auto's look for lane paint on a
        kerbed road), and with signs beside the lane path their search of that frame starts."""
        self.perception.answered()

    def _signs(self, image: np.ndarray, pose: OdoPose, small: np.ndarray) -> tuple[SignDetection, ...]:
        found, confirmed, at = self.perception.signs_now(image, pose, small)
        if at is None:
            return ()
        dc = self.config.drive
        placed = sign_positions(confirmed, found, self.perception.camera, at, dc.sign_size_m, dc.sign_min_aspect,
                                dc.sign_max_lateral_m)
        self.behaviour.observe_signs(placed)
        return found

    @property
    def confirmed(self) -> list[SignDetection]:
        return self.perception.confirmed

    def use_camera(self, camera: CameraConfig) -> None:
        """Read the frames to come with this camera (one measured from the stream's own frames)."""
        self.perception.use_camera(camera)

    def reset(self) -> None:
        self.perception.reset()
        self.behaviour.reset()
        if self.pilot is not None:
            self.pilot.reset()
        self.odometry.reset()
        self.seq = 0

    def close(self) -> None:
        self.perception.close()

    def __enter__(self) -> "DriveStack":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
