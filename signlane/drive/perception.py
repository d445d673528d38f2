"""Perception built once, for every user: the configured lane method on a working copy of each
frame, junction openings from the same scan, and the sign stage on the full frame.

`signlane infer` (signlane/pipeline.py) and the closed-loop drive stack (signlane/drive/stack.py:
`drive`, `sim --with-driver`, `run`) both build theirs here, so a method, a model or a camera
setting reaches all of them the same way. Camera-dependent parts are built for the stream's
frame size on its first frame (and again if the size changes).
"""
from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np

from signlane import lanes
from signlane.config import CameraConfig, Config
from signlane.drive.signs import SignWorker, stage_failure
from signlane.junction import JunctionDetector, JunctionView, moved_on, view_from_scan, with_road_end
from signlane.lanes.auto import road_state
from signlane.signs.face_rows import RowBand, face_rows
from signlane.types import LaneEstimate, SignDetection


class PerceptionStack:
    """lanes_width: lanes and junctions run on frames scaled to this width (0 = as they come).
    sync_signs False runs the sign stage in a worker thread on the newest frame (real time)."""

    def __init__(self, config: Config, lanes_width: int = 0, sync_signs: bool = True, junctions: bool = True,
                 after_answer: bool = False, sign_rows: bool = False):
        """after_answer: the caller calls answered() once each frame's command is out (a driver):
        the lane method may then put work off until then that only later frames read (auto's
        `edges_after_answer`), and a painted road's junction detector runs then on the frame, its
        view read by the next (junction_view); off, each frame's outputs are all its own (infer).
        sign_rows: the frames come from the configured camera on a car, so signs are searched
        only in the rows where their faces can stand (config.drive.sign_search_near_m,
        signs/face_rows.py); off for photos and footage from any camera (infer)."""
        self.config = config
        self.sign_rows = sign_rows
        self.after_answer = after_answer
        self.lanes_width = lanes_width
        self.with_junctions = junctions
        cfg_lanes = config.lanes
        lanes.params_for(cfg_lanes.method, cfg_lanes.variant, **cfg_lanes.overrides())  # fail early on a bad name
        self.signs = None
        self._worker = None
        self._held = None  # (frame, pose) for the worker, once the frame's answer is out
        if config.signs.enabled:
            from signlane.signs.stage import SignStage
            self.signs = SignStage(config.signs)
            if not sync_signs:
                self._worker = SignWorker(self.signs)
        self._size: tuple[int, int] | None = None
        self.lane = self.junctions = self.camera = self.small_camera = None
        self.scaled = (0, 0)
        self._frames = 0  # frames whose junction view was asked for
        # a painted road's junction detection put off until the frame's answer is out: (frame
        # number, lane copy, lane width, road maps, odometry metres), and the view it made:
        # (frame number, view, odometry metres)
        self._junction_work: tuple | None = None
        self._painted_view: tuple[int, JunctionView, float] | None = None

    def setup(self, width: int, height: int) -> None:
        if self._size == (width, height):
            return
        cfg = self.config
        lw = self.lanes_width
        scale = lw / width if 0 < lw < width else 1.0
        self.scaled = (round(width * scale), round(height * scale))
        self.camera = cfg.camera.camera(width, height)
        self.small_camera = cfg.camera.camera(*self.scaled)
        self.lane = lanes.get(cfg.lanes.method, camera=self.small_camera, variant=cfg.lanes.variant,
                              **cfg.lanes.overrides())
        if self.after_answer and hasattr(self.lane.params, "edges_after_answer"):
            self.lane.params = replace(self.lane.params, edges_after_answer=True)
        self.junctions = JunctionDetector(self.small_camera) if self.with_junctions else None
        self._junction_work = self._painted_view = None  # another detector: what the last one saw is not its
        if self.signs is not None and self.sign_rows:
            dc = cfg.drive
            rows = face_rows(self.camera, dc.sign_search_near_m, dc.sign_height_m - dc.sign_size_m / 2,
                             dc.sign_height_m + dc.sign_size_m / 2)
            # the band is checked by the stage (RowBand) and used only with a classifier to check it
            self.signs.band = None if rows is None else RowBand((width, height), rows)
        self._size = (width, height)

    def use_camera(self, camera: CameraConfig) -> None:
        """Another camera for the frames to come (one measured from a stream's own frames):
        the camera-dependent parts are built anew on the next frame."""
        if camera != self.config.camera:
            self.config = replace(self.config, camera=camera)
            self._size = None

    @property
    def confirmed(self) -> list[SignDetection]:
        """Signs confirmed over the last frames (N of M)."""
        return list(self.signs.confirmed) if self.signs is not None else []

    def lanes_on(self, image: np.ndarray) -> tuple[LaneEstimate, np.ndarray]:
        """The lane in the working frame's pixels, and that working frame (uint8 BGR)."""
        h, w = image.shape[:2]
        self.setup(w, h)
        small = image if self.scaled == (w, h) else cv2.resize(image, self.scaled, interpolation=cv2.INTER_AREA)
        return self.lane(small), small

    def junction_view(self, small: np.ndarray, lane: LaneEstimate, odo_m: float | None = None):
        """(junction view, two_lane): on a kerbed carriageway the openings are where its edges
        jump away; on painted lanes where the edge line is missing, a road ending ahead from the
        scan.

        With after_answer and the car's odometry (metres driven, `odo_m`), a painted road's
        detector (about 0.7 ms at 320x240) runs on the frame once its command is out (answered(),
        else first thing on the next frame), and the frame is read with the frame before's view,
        its openings moved nearer by the metres driven since (a side road is seen 30 m ahead and
        a frame is at most a few tenths of a metre of driving); the first frame of a painted
        stretch has no view."""
        self._frames += 1
        road = road_state(self.lane.state)
        two_lane = road is None or road.two_lane
        if not two_lane:
            view = view_from_scan(road.scan)
        else:
            maps = getattr(self.lane.state, "maps", None)
            if self.after_answer and odo_m is not None:
                self.settle_junctions()  # the frame before's, if its caller never said it had answered
                before = self._painted_view
                view = moved_on(before[1], odo_m - before[2]) if before and before[0] == self._frames - 1 \
                    else JunctionView(None, None, None)
                self._junction_work = (self._frames, small, lane.lane_width_m or None, maps, odo_m)
            else:
                view = self.junctions.detect(small, lane.lane_width_m or None, maps)
            if road is not None and road.scan is not None:
                view = with_road_end(view, road.scan)
        return view, two_lane

    def settle_junctions(self) -> None:
        """The painted road's junction detection put off from the last frame, made now."""
        work, self._junction_work = self._junction_work, None
        if work is not None:
            frame, small, width, maps, odo_m = work
            self._painted_view = (frame, self.junctions.detect(small, width, maps), odo_m)

    def signs_now(self, image: np.ndarray, pose=None, small: np.ndarray | None = None
                  ) -> tuple[tuple[SignDetection, ...], list, object]:
        """(found, confirmed, the pose they were seen at): in step with the frame, or the worker's
        newest result (found empty and pose None when it has none yet). SignStageError on failure.
        small: the lane copy, which the proposals take as their half-size frame when it is one."""
        if self.signs is None:
            return (), [], None
        if self._worker is None:
            try:
                found, confirmed = self.signs.step(image, small)
            except Exception as e:
                raise stage_failure(e) from e
            return tuple(found), list(confirmed), pose
        self.release_signs()  # the previous frame's, if its caller never said it had answered
        self._held = (image, pose)
        found, confirmed, at = self._worker.latest()
        return tuple(found), confirmed, at

    def answered(self) -> None:
        """The last frame's command is out: the work put off until then (the lane method's, the
        sign stage's band check, the sign search of the frame with signs beside the lane path)."""
        self.release_signs()
        if self.signs is not None and self._worker is None:
            try:
                self.signs.settle()  # a band check due on the frame (signs/face_rows.py)
            except Exception as e:
                raise stage_failure(e) from e
        if self.lane is not None:
            self.lane.settle()
        self.settle_junctions()

    def release_signs(self) -> None:
        """Hand the frame held back by `signs_now` to the sign worker: call it once the frame's
        command is out. The worker then searches in the gap before the next frame instead of
        beside the steering path, whose answer would otherwise wait on the interpreter lock
        while the search runs Python. Its result is read on the next frame, as before."""
        held, self._held = self._held, None
        if held is not None and self._worker is not None:
            self._worker.submit(*held)

    @property
    def sign_ms(self) -> dict[str, float]:
        """The sign stage's parts of the last frame, when it runs in step (in the worker they are
        another thread's)."""
        if self.signs is None or self._worker is not None:
            return {}
        return {f"signs_{k}": v for k, v in self.signs.last_ms.items()}

    def forget_tracks(self) -> None:
        """The lane tracker's last fit no longer applies (e.g. after a junction)."""
        keep = getattr(self.lane.state, "forget_tracks", None)
        self.lane.state = keep() if keep else None

    def in_frame_pixels(self, lane: LaneEstimate, width: int) -> LaneEstimate:
        """The lane's boundaries in the frame's own pixels (the working frame may be smaller)."""
        if self.scaled[0] == width:
            return lane
        k = width / self.scaled[0]
        return replace(lane, left=None if lane.left is None else lane.left * k,
                       right=None if lane.right is None else lane.right * k)

    def reset(self) -> None:
        self._junction_work = self._painted_view = None
        if self._size is not None:
            self.lane.reset()
            if self.junctions is not None:
                self.junctions.reset()
        if self.signs is not None:
            self.signs.reset()

    def close(self) -> None:
        if self._worker is not None:
            self._worker.close()
            self._worker = None
