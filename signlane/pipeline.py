"""Frame -> Perception -> Command, composing the configured lane method, sign stage and controller."""
from __future__ import annotations

import time

from signlane import lanes
from signlane.config import Config
from signlane.control import ThrottlePolicy, make_controller
from signlane.types import Command, Frame, Perception, SignDetection


class Pipeline:
    """Stateful per stream (lane tracking, controller smoothing): one per video or camera."""

    def __init__(self, config: Config | None = None):
        self.config = config or Config()
        self._camera_size: tuple[int, int] | None = None
        self._lane = None
        self._controller = None
        self._throttle = ThrottlePolicy(self.config.control.cruise)
        self.signs = None
        cfg_lanes = self.config.lanes
        lanes.params_for(cfg_lanes.method, cfg_lanes.variant, **cfg_lanes.overrides())  # fail early on a bad name
        make_controller(self.config.control.controller)
        if self.config.signs.enabled:
            from signlane.signs.stage import SignStage
            self.signs = SignStage(self.config.signs)

    @property
    def confirmed(self) -> list[SignDetection]:
        """Signs confirmed over the last frames (N of M)."""
        return self.signs.confirmed if self.signs is not None else []

    def _setup(self, width: int, height: int) -> None:
        """Camera-dependent parts are built for the stream's frame size."""
        if self._camera_size == (width, height):
            return
        cfg = self.config
        camera = cfg.camera.camera(width, height)
        self._lane = lanes.get(cfg.lanes.method, camera=camera, variant=cfg.lanes.variant, **cfg.lanes.overrides())
        self._controller = make_controller(cfg.control.controller, camera)
        self._camera_size = (width, height)

    def step(self, frame: Frame, speed: float = 0.0) -> tuple[Perception, Command]:
        h, w = frame.image_bgr.shape[:2]
        self._setup(w, h)
        timing: dict[str, float] = {}
        t0 = time.perf_counter()
        lane = self._lane(frame.image_bgr)
        t1 = time.perf_counter()
        timing["lanes"] = (t1 - t0) * 1e3
        signs: tuple[SignDetection, ...] = ()
        if self.signs is not None:
            signs, _ = self.signs.step(frame.image_bgr)
            timing["signs"] = (time.perf_counter() - t1) * 1e3
        t2 = time.perf_counter()
        steering = self._controller.step(lane, speed)
        throttle, state = self._throttle.throttle(lane)
        timing["control"] = (time.perf_counter() - t2) * 1e3
        return Perception(frame, lane, signs, timing), Command(steering, throttle, state)

    def reset(self) -> None:
        """Forget tracking state (a new video or a jump in time)."""
        if self._lane is not None:
            self._lane.reset()
        if self._controller is not None:
            self._controller.reset()
        if self.signs is not None:
            self.signs.reset()

    def close(self) -> None:
        self.reset()

    def __enter__(self) -> "Pipeline":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
