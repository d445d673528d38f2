"""Learned `segnet`: a small segmentation network marks lane paint; the sliding-window back-end
turns that mask into the ego lane.

Steps: the frame, resized to the model's input, gives P(lane marking) at the model's output size
(`seg_model`, the one pre/post-processing); that map is warped straight into the metric
bird's-eye view (one homography: output pixel -> frame pixel -> bird's-eye) and thresholded; the
sliding-window method's bases, windows, ego-pair choice, plausibility checks and shared fits
(`sliding_window.lanes_from_binary`, `geometry`) give the LaneEstimate. Where the classical
binary guesses paint from brightness, the network has learned it from exact masks under night,
rain, glare, shadows and worn paint. The debug mask is the network's marking mask at the
frame's size (what `infer --save-masks` writes), made only where a viewer asks for it
(`LaneEstimate.with_masks`), as is the road mask.

A road model (seg_model.ROAD_CLASSES; the shipped model is one) also gives P(road surface). Where the paint gives no lane
(VIA's kerbed carriageway has none; worn or hidden paint), the carriageway is found as
`road-edges` finds it, from the model's road and paint instead of colour rules
(`road_edges.carriageway` with the maps), and the lane is the carriageway, the car keeping its
middle (on a road whose middle has shown a centre line, the right half of it, as `auto` does):
`LaneEstimate.basis` is then "edges" (else "paint"), and `drivable_mask` carries the
road at the frame's size (`infer --save-masks` writes it as <stem>_drivable.png).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cache

import cv2
import numpy as np

from signlane.camera import BirdsEye, Camera
from signlane.lanes import register
from signlane.lanes import seg_model
from signlane.lanes.geometry import camera_for
from signlane.lanes.road_edges import (RoadEdgesParams, RoadEdgesState, carriageway, carriageway_estimate,
                                       right_half_estimate)
from signlane.lanes.sliding_window import SlidingWindowParams, SlidingWindowState, lanes_from_binary
from signlane.types import LaneEstimate

NAME = "segnet"


@dataclass(frozen=True)
class SegNetParams:
    """model "" = the shipped signlane/models/lanes.onnx. The back-end is sliding-window's robust
    variant; its stripe-finding parameters are unused (the network gives the binary)."""

    model: str = ""
    threads: int = 1  # onnxruntime intra-op threads: one leaves the other cores to the car
    threshold: float = seg_model.MASK_THRESHOLD  # P(marking) above which a pixel is paint
    backend: SlidingWindowParams = field(default_factory=SlidingWindowParams)
    road: RoadEdgesParams = field(default_factory=RoadEdgesParams)  # the drivable area's edge scan

    @classmethod
    def published(cls) -> SegNetParams:
        return cls()  # a learned method has no published baseline: the same as the default


@dataclass(frozen=True)
class SegNetState:
    paint: SlidingWindowState | None = None
    road: RoadEdgesState = field(default_factory=RoadEdgesState)

    def forget_tracks(self) -> "SegNetState":
        return SegNetState(None, self.road.forget_tracks())


@register(NAME, SegNetParams)
def segnet(image_bgr: np.ndarray, camera: Camera | None, params: SegNetParams,
           state: SegNetState | None) -> tuple[LaneEstimate, SegNetState]:
    """Lane from a uint8 (H, W, 3) BGR frame (grayscale is accepted); see the module docstring."""
    image_bgr = image_bgr if image_bgr.ndim == 3 else cv2.cvtColor(image_bgr, cv2.COLOR_GRAY2BGR)
    h, w = image_bgr.shape[:2]
    model = seg_model.load(seg_model.resolve(params.model), params.threads)
    state = state or SegNetState()
    paint_state = state.paint or SlidingWindowState(lane_width_m=params.backend.lane_width_m)
    if min(h, w) < 16:  # too small to hold a lane marking
        return LaneEstimate(NAME, False, debug_mask=np.zeros((h, w), np.uint8)), \
            SegNetState(SlidingWindowState(None, None, paint_state.lane_width_m, False, paint_state.misses + 1), state.road)
    image_bgr = np.ascontiguousarray(image_bgr[:, :, :3])
    maps = model.frame_maps(image_bgr, params.threshold)
    cam = camera_for(image_bgr, camera)
    est, paint_state = paint_lane(NAME, maps, cam, params.backend, state.paint, own_debug=False)
    if est.found or maps.road is None:
        # the network's masks at the frame's size (two resizes: 0.25 ms a frame at 640x480) are for
        # viewers only (infer --save-masks, the monitor): made where one asks (with_masks)
        return replace(est, masks_later=_frame_masks(maps, w, h)), SegNetState(paint_state, state.road)
    edges, road_state = edges_lane(NAME, image_bgr, cam, params.road, state.road, maps)
    # (its road mask, the model's road at the frame's size, the edge scan has made already)
    return replace(edges, drivable_mask=None, masks_later=_frame_masks(maps, w, h, edges.drivable_mask)), \
        SegNetState(paint_state, road_state)


def _frame_masks(maps: seg_model.FrameMaps, w: int, h: int, road: np.ndarray | None = None):
    """LaneEstimate.masks_later for a frame w x h: its (marking, road or None) masks, made once
    however many viewers ask (the monitor's mask and road views both do); `road`: one made already."""
    @cache
    def made():
        drivable = road if road is not None or maps.road is None else maps.frame_mask(maps.road, w, h)
        return maps.frame_mask(maps.marking, w, h), drivable
    return made


def paint_lane(method: str, maps: seg_model.FrameMaps, cam: Camera, backend: SlidingWindowParams,
               state: SlidingWindowState | None, own_debug: bool = True
               ) -> tuple[LaneEstimate, SlidingWindowState]:
    """The ego lane from the model's lane paint: its P(marking) warped straight into the
    sliding-window back-end's bird's-eye view (one homography: output pixel -> frame pixel ->
    bird's-eye), thresholded, and the back-end's bases, windows, ego pair and fits. The debug
    mask is the back-end's (the kept lines' pixels), or none with own_debug=False."""
    def binary_of(bev: BirdsEye, valid: np.ndarray) -> np.ndarray:
        return (maps.warped(maps.marking, bev.image_to_bev_h(), bev.size) & (valid > 0)).astype(np.uint8) * 255
    return lanes_from_binary(method, binary_of, cam, backend, state, own_debug=own_debug)


def edges_lane(method: str, image_bgr: np.ndarray, cam: Camera, p: RoadEdgesParams, state: RoadEdgesState,
               maps: seg_model.FrameMaps) -> tuple[LaneEstimate, RoadEdgesState]:
    """The lane from the model's drivable area (road-edges' scan of the model's road): the
    carriageway, or, on a road whose middle has shown a centre line over the frames (the
    model's paint there, as road-edges measures it), its right half."""
    h, w = image_bgr.shape[:2]
    left, right, width, new, mask = carriageway(image_bgr, cam, p, state, maps)
    if new.two_lane and left is not None and right is not None:
        return right_half_estimate(method, cam, left, right, width, mask, (h, w)), new
    return carriageway_estimate(method, cam, left, right, width, new, mask, (h, w)), new
