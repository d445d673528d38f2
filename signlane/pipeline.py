"""Frame -> Perception -> Command for `signlane infer`: the shared perception builder
(signlane/drive/perception.py) on the frame as it comes, and the configured open-loop steering
controller (a file of images has no speed, wheel angle or time to run the closed loop on)."""
from __future__ import annotations

import time

from signlane.config import CameraConfig, Config
from signlane.control import ThrottlePolicy, make_controller
from signlane.drive.perception import PerceptionStack
from signlane.types import Command, Frame, Perception, SignDetection


class Pipeline:
    """Stateful per stream (lane tracking, controller smoothing): one per video or camera."""

    def __init__(self, config: Config | None = None):
        self.config = config or Config()
        # full-size frames, signs in step, no junction reading: what infer reports per frame
        self.perception = PerceptionStack(self.config, lanes_width=0, sync_signs=True, junctions=False)
        self.signs = self.perception.signs
        self._throttle = ThrottlePolicy(self.config.control.cruise)
        self._controller = None
        self._camera_size: tuple[int, int] | None = None
        make_controller(self.config.control.controller)  # fail early on a bad name
        from signlane.pilot import from_config
        self.pilot = from_config(self.config.pilot)  # steers in place of the controller where set

    @property
    def confirmed(self) -> list[SignDetection]:
        """Signs confirmed over the last frames (N of M)."""
        return self.perception.confirmed

    def step(self, frame: Frame, speed: float = 0.0) -> tuple[Perception, Command]:
        h, w = frame.image_bgr.shape[:2]
        if self._camera_size != (w, h):
            self._controller = make_controller(self.config.control.controller, self.camera.camera(w, h))
            self._camera_size = (w, h)
        timing: dict[str, float] = {}
        t0 = time.perf_counter()
        lane, _ = self.perception.lanes_on(frame.image_bgr)
        t1 = time.perf_counter()
        timing["lanes"] = (t1 - t0) * 1e3
        signs: tuple[SignDetection, ...] = ()
        if self.signs is not None:
            signs, _ = self.signs.step(frame.image_bgr)  # its own errors (a model's) reach infer's one-line report
            timing["signs"] = (time.perf_counter() - t1) * 1e3
        t2 = time.perf_counter()
        steering = self._controller.step(lane, speed)
        throttle, state = self._throttle.throttle(lane)
        t3 = time.perf_counter()
        timing["control"] = (t3 - t2) * 1e3
        if self.pilot is not None:  # no planner here: straight on along the lane
            steering = self.pilot.step(frame.image_bgr, "straight").steering
            timing["pilot"] = (time.perf_counter() - t3) * 1e3
        return Perception(frame, lane, signs, timing), Command(steering, throttle, state)

    def use_camera(self, camera: CameraConfig) -> None:
        """Read the frames to come with this camera (infer measures each input's own)."""
        self.perception.use_camera(camera)
        self._camera_size = None  # the controller is rebuilt for it on the next frame

    @property
    def camera(self) -> CameraConfig:
        """The camera the frames are read with now."""
        return self.perception.config.camera

    def reset(self) -> None:
        """Forget tracking state (a new video or a jump in time)."""
        self.perception.reset()
        if self._controller is not None:
            self._controller.reset()

    def close(self) -> None:
        self.reset()
        self.perception.close()

    def __enter__(self) -> "Pipeline":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
