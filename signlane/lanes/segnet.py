"""Learned `segnet`: a small segmentation network marks lane paint; the sliding-window back-end
turns that mask into the ego lane.

Steps: the frame, resized to the model's input, gives P(lane marking) at the model's output size
(`seg_model`, the one pre/post-processing); that map is warped straight into the metric
bird's-eye view (one homography: output pixel -> frame pixel -> bird's-eye) and thresholded; the
sliding-window method's bases, windows, ego-pair choice, plausibility checks and shared fits
(`sliding_window.lanes_from_binary`, `geometry`) give the LaneEstimate. Where the classical
binary guesses paint from brightness, the network has learned it from exact masks under night,
rain, glare, shadows and worn paint. The debug mask is the network's marking mask at the
frame's size (what `infer --save-masks` writes).

A road model (seg_model.ROAD_CLASSES) also gives P(road surface). Where the paint gives no lane
(VIA's kerbed carriageway has none; worn or hidden paint), the drivable area warped into the
road-edges bird's-eye view is scanned for the carriageway's edges as `road-edges` scans its
colour mask (`road_edges.scan_edges`), and the lane is the carriageway, the car keeping its
middle (on a road whose middle has shown a centre line, the right half of it, as `auto` does):
`LaneEstimate.basis` is then "edges" (else "paint"), and `drivable_mask` carries the
road at the frame's size (`infer --save-masks` writes it as <stem>_drivable.png).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import cv2
import numpy as np

from signlane.camera import BirdsEye, Camera
from signlane.lanes import register
from signlane.lanes import seg_model
from signlane.lanes.geometry import Boundary, camera_for, estimate_from_fits
from signlane.lanes.road_edges import (RoadEdgesParams, RoadEdgesState, carriageway_estimate, centre_paint,
                                       fit_edge, road_edges_bev, scan_edges)
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
    model = seg_model.load(params.model or str(seg_model.DEFAULT_MODEL), params.threads)
    state = state or SegNetState()
    paint_state = state.paint or SlidingWindowState(lane_width_m=params.backend.lane_width_m)
    if min(h, w) < 16:  # too small to hold a lane marking
        return LaneEstimate(NAME, False, debug_mask=np.zeros((h, w), np.uint8)), \
            SegNetState(SlidingWindowState(None, None, paint_state.lane_width_m, False, paint_state.misses + 1), state.road)
    marking, road = model.maps([np.ascontiguousarray(image_bgr[:, :, :3])])
    prob = marking[0]
    cam = camera_for(image_bgr, camera)
    to_frame = _output_to_frame(prob.shape, w, h)

    def binary_of(bev: BirdsEye, valid: np.ndarray) -> np.ndarray:
        p = cv2.warpPerspective(prob, bev.image_to_bev_h() @ to_frame, bev.size, flags=cv2.INTER_LINEAR,
                                borderMode=cv2.BORDER_CONSTANT)
        return ((p > params.threshold) & (valid > 0)).astype(np.uint8) * 255

    debug = seg_model.to_frame_mask(prob, w, h, params.threshold)
    est, paint_state = lanes_from_binary(NAME, binary_of, cam, params.backend, state.paint, debug_mask=debug)
    if road is None:
        return est, SegNetState(paint_state, state.road)
    drivable = seg_model.to_frame_mask(road[0], w, h, params.threshold)
    est = replace(est, drivable_mask=drivable)
    if est.found:
        return est, SegNetState(paint_state, state.road)
    edges, road_state = _from_edges(road[0], to_frame, cam, params, state.road, debug, drivable, prob)
    return edges, SegNetState(paint_state, road_state)


def _from_edges(road_prob: np.ndarray, to_frame: np.ndarray, cam: Camera, params: SegNetParams,
                state: RoadEdgesState, debug: np.ndarray, drivable: np.ndarray,
                marking_prob: np.ndarray | None = None) -> tuple[LaneEstimate, RoadEdgesState]:
    """The lane from the drivable area's edges (road-edges' scan on the network's road): the
    carriageway, or, on a road whose middle has shown a centre line over the frames (the
    network's marking map there, as road-edges measures it), its right half."""
    p = params.road
    bev = road_edges_bev(cam, p, state)
    visible = bev.visible() > 0
    warped = cv2.warpPerspective(road_prob, bev.image_to_bev_h() @ to_frame, bev.size, flags=cv2.INTER_LINEAR,
                                 borderMode=cv2.BORDER_CONSTANT)
    road = (warped > params.threshold) & visible
    scan = scan_edges(road, visible, bev, p, state.width_m or p.width_m)
    left = fit_edge(np.column_stack([scan.run_l, scan.y])[scan.ok_l], p)
    right = fit_edge(np.column_stack([scan.run_r, scan.y])[scan.ok_r], p)
    good = left is not None and right is not None and p.min_width_m < scan.width_m < p.max_width_m
    memory = state.centre_paint
    if good and marking_prob is not None:
        paint = cv2.warpPerspective(marking_prob, bev.image_to_bev_h() @ to_frame, bev.size,
                                    flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT) > params.threshold
        memory = centre_paint(paint & visible, bev, scan, p, memory)
    new = replace(state, width_m=scan.width_m if good else state.width_m, bev=bev, scan=scan, centre_paint=memory)
    if new.two_lane and left is not None and right is not None:
        mid = Boundary((left.coeffs + right.coeffs) / 2, left.y_range)
        est = estimate_from_fits(NAME, cam, mid, right, scan.width_m / 2, 0.5, debug)
        return replace(est, basis="edges", drivable_mask=drivable), new
    est = carriageway_estimate(NAME, cam, left, right, scan.width_m, new, None, debug.shape)
    return replace(est, debug_mask=debug, drivable_mask=drivable), new


def _output_to_frame(shape: tuple[int, int], width: int, height: int) -> np.ndarray:
    """3x3: model output pixel (centres) -> frame pixel, for an output of `shape` (h, w)."""
    sx, sy = width / shape[1], height / shape[0]
    return np.array([[sx, 0.0, 0.5 * sx - 0.5], [0.0, sy, 0.5 * sy - 0.5], [0.0, 0.0, 1.0]])
