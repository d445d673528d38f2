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
"""
from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from signlane.camera import BirdsEye, Camera
from signlane.lanes import register
from signlane.lanes import seg_model
from signlane.lanes.geometry import camera_for
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

    @classmethod
    def published(cls) -> SegNetParams:
        return cls()  # a learned method has no published baseline: the same as the default


@register(NAME, SegNetParams)
def segnet(image_bgr: np.ndarray, camera: Camera | None, params: SegNetParams,
           state: SlidingWindowState | None) -> tuple[LaneEstimate, SlidingWindowState]:
    """Lane from a uint8 (H, W, 3) BGR frame (grayscale is accepted); see the module docstring."""
    image_bgr = image_bgr if image_bgr.ndim == 3 else cv2.cvtColor(image_bgr, cv2.COLOR_GRAY2BGR)
    h, w = image_bgr.shape[:2]
    model = seg_model.load(params.model or str(seg_model.DEFAULT_MODEL), params.threads)
    if min(h, w) < 16:  # too small to hold a lane marking
        state = state or SlidingWindowState(lane_width_m=params.backend.lane_width_m)
        return LaneEstimate(NAME, False, debug_mask=np.zeros((h, w), np.uint8)), \
            SlidingWindowState(None, None, state.lane_width_m, False, state.misses + 1)
    prob = model.probabilities([np.ascontiguousarray(image_bgr[:, :, :3])])[0]
    cam = camera_for(image_bgr, camera)
    to_frame = _output_to_frame(prob.shape, w, h)

    def binary_of(bev: BirdsEye, valid: np.ndarray) -> np.ndarray:
        p = cv2.warpPerspective(prob, bev.image_to_bev_h() @ to_frame, bev.size, flags=cv2.INTER_LINEAR,
                                borderMode=cv2.BORDER_CONSTANT)
        return ((p > params.threshold) & (valid > 0)).astype(np.uint8) * 255

    debug = seg_model.to_frame_mask(prob, w, h, params.threshold)
    return lanes_from_binary(NAME, binary_of, cam, params.backend, state, debug_mask=debug)


def _output_to_frame(shape: tuple[int, int], width: int, height: int) -> np.ndarray:
    """3x3: model output pixel (centres) -> frame pixel, for an output of `shape` (h, w)."""
    sx, sy = width / shape[1], height / shape[0]
    return np.array([[sx, 0.0, 0.5 * sx - 0.5], [0.0, sy, 0.5 * sy - 0.5], [0.0, 0.0, 1.0]])
