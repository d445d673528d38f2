"""Lane-marking segmentation model runtime: the ONNX session with its contract, and the one
pre- and post-processing that training, export parity, evaluation and the runtime all call.

The model takes whole frames resized to its input size (any aspect: a 16:9 frame is squeezed
like it was in training) and returns class logits at its output size: (N, 2, h, w) for
background / lane marking (CLASSES), or, for a road model, (N, 4, h, w) for background / lane
marking / off road / drivable (ROAD_CLASSES: two independent two-class heads, since paint lies on
the road). The metadata's class list says which a file is; `marking_probability` and
`drivable_probability` turn the logits into P(marking) and P(road surface) at that size.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import cv2
import numpy as np

from signlane.label_masks import IGNORE
from signlane.onnx_model import InputSpec, ModelError, OnnxModel, prepare_input

TASK = "lane-segmentation"
CLASSES = ("background", "lane_marking")
ROAD_CLASSES = ("background", "lane_marking", "off_road", "drivable")
DEFAULT_MODEL = Path(__file__).resolve().parent.parent / "models" / "lanes.onnx"
DEFAULT_SPEC = InputSpec(160, 120, "RGB", "NCHW", 1.0 / 255.0, (0.45, 0.45, 0.45), (0.25, 0.25, 0.25))
MASK_THRESHOLD = 0.5


def preprocess_frames(frames_bgr: list[np.ndarray], spec: InputSpec = DEFAULT_SPEC) -> np.ndarray:
    """uint8 BGR frames (H, W, 3), any size -> float32 (N, 3, spec.height, spec.width) input."""
    return prepare_input(frames_bgr, spec, "frame")


def _pair_probability(logits: np.ndarray, k: int) -> np.ndarray:
    """The softmax of channels k, k + 1 as P(k + 1) = 1 / (1 + exp(-(l[k+1] - l[k]))), in place
    on one float32 array (it runs twice a frame on the car)."""
    d = np.subtract(logits[:, k + 1], logits[:, k], dtype=np.float32)
    np.clip(d, -60.0, 60.0, out=d)
    np.negative(d, out=d)
    np.exp(d, out=d)
    d += 1.0
    return np.reciprocal(d, out=d)


def marking_probability(logits: np.ndarray) -> np.ndarray:
    """(N, 2 or 4, h, w) logits -> float32 (N, h, w) P(lane marking) (the first pair's softmax)."""
    return _pair_probability(logits, 0)


def drivable_probability(logits: np.ndarray) -> np.ndarray:
    """(N, 4, h, w) logits of a road model -> float32 (N, h, w) P(road surface) (the second pair)."""
    if logits.shape[1] != len(ROAD_CLASSES):
        raise ValueError(f"logits have {logits.shape[1]} channels; a road model's have {len(ROAD_CLASSES)}")
    return _pair_probability(logits, 2)


def mask_target(mask: np.ndarray, size: tuple[int, int], min_cover: float = 0.25,
                ignore: np.ndarray | None = None) -> np.ndarray:
    """A label mask uint8 or bool (H, W) at the frame's size, nonzero = marking, and optionally bool
    (H, W) pixels without a label (a dataset's 255s: signlane.label_masks) -> uint8 (h, w) target
    at the model's output size (w, h): 1 where paint covers min_cover of a cell, so lines thinner
    than a cell survive the downscale; 0 where it would not even if every unlabelled pixel of the
    cell were paint; 255 (ignore) in between. Without unlabelled pixels there is no 255."""
    cover = cv2.resize((mask > 0).astype(np.float32), size, interpolation=cv2.INTER_AREA)
    target = (cover >= min_cover).astype(np.uint8)
    if ignore is not None and ignore.any():
        unknown = cv2.resize(ignore.astype(np.float32), size, interpolation=cv2.INTER_AREA)
        target[(target == 0) & (cover + unknown >= min_cover)] = IGNORE
    return target


def resolve(path: str) -> str:
    """A config's model value as a file: "" or "shipped" = the shipped signlane/models/lanes.onnx."""
    return str(DEFAULT_MODEL) if path in ("", "shipped") else path


def output_to_frame(shape: tuple[int, int], width: int, height: int) -> np.ndarray:
    """3x3: model output pixel (centres) -> frame pixel, for an output of `shape` (h, w)."""
    sx, sy = width / shape[1], height / shape[0]
    return np.array([[sx, 0.0, 0.5 * sx - 0.5], [0.0, sy, 0.5 * sy - 0.5], [0.0, 0.0, 1.0]])


@dataclass(frozen=True)
class FrameMaps:
    """A model's maps of one frame at its output size: P(lane marking), P(road surface) (None
    for a marking model), and `to_frame`, the 3x3 from output pixels to the frame's."""

    marking: np.ndarray
    road: np.ndarray | None
    to_frame: np.ndarray
    threshold: float = MASK_THRESHOLD

    def warped(self, prob: np.ndarray, frame_to_view: np.ndarray, size: tuple[int, int]) -> np.ndarray:
        """bool mask of `prob` (one of the maps) above the threshold in a view of the frame
        (`frame_to_view` 3x3, e.g. a bird's-eye view's image_to_bev_h(); size (w, h)): one
        warp, straight from the output's pixels."""
        p = cv2.warpPerspective(prob, frame_to_view @ self.to_frame, size, flags=cv2.INTER_LINEAR,
                                borderMode=cv2.BORDER_CONSTANT)
        return p > self.threshold

    def road_in(self, frame_to_view: np.ndarray, size: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
        """(road, paint) bool masks in a view of the frame (as `warped`): paint lies on the road,
        so the road includes it."""
        paint = self.warped(self.marking, frame_to_view, size)
        return self.warped(self.road, frame_to_view, size) | paint, paint

    def frame_mask(self, prob: np.ndarray, width: int, height: int) -> np.ndarray:
        """uint8 (height, width) 0/255 mask of one of the maps at the frame's size."""
        return to_frame_mask(prob, width, height, self.threshold)


def to_frame_mask(prob: np.ndarray, width: int, height: int, threshold: float = MASK_THRESHOLD) -> np.ndarray:
    """float32 (h, w) P(marking) -> uint8 (height, width) 0/255 mask at the frame's size."""
    up = cv2.resize(prob, (width, height), interpolation=cv2.INTER_LINEAR)
    return cv2.compare(up, threshold, cv2.CMP_GT)  # 0/255 in one pass (a frame-sized array)


class LaneSegModel:
    """The segmentation model with its contract read from the ONNX metadata: a marking model
    (CLASSES) or a road model (ROAD_CLASSES, `has_drivable`)."""

    def __init__(self, path: str | Path = DEFAULT_MODEL, threads: int = 1):
        self.model = OnnxModel(path, TASK, threads, output_rank=4)
        if tuple(self.model.classes) not in (CLASSES, ROAD_CLASSES):
            raise ModelError(f"{path}: classes {self.model.classes} are neither {list(CLASSES)} nor "
                             f"{list(ROAD_CLASSES)}")
        self.classes = tuple(self.model.classes)
        self.has_drivable = self.classes == ROAD_CLASSES
        self.spec = self.model.input

    def logits(self, frames_bgr: list[np.ndarray]) -> np.ndarray:
        out = self.model.run(preprocess_frames(frames_bgr, self.spec))
        if out.ndim != 4 or out.shape[1] != len(self.classes):
            raise ModelError(f"{self.model.path}: output shape {out.shape} is not (N, {len(self.classes)}, h, w)")
        return out

    def probabilities(self, frames_bgr: list[np.ndarray]) -> np.ndarray:
        """float32 (N, h, w) P(lane marking) at the model's output size."""
        return marking_probability(self.logits(frames_bgr))

    def frame_maps(self, image_bgr: np.ndarray, threshold: float = MASK_THRESHOLD) -> FrameMaps:
        """The maps of one uint8 BGR frame (any size), with where they lie in it."""
        marking, road = self.maps([image_bgr])
        h, w = image_bgr.shape[:2]
        return FrameMaps(marking[0], None if road is None else road[0],
                         output_to_frame(marking.shape[1:], w, h), threshold)

    def maps(self, frames_bgr: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray | None]:
        """(P(lane marking), P(road surface) or None for a marking model), each float32 (N, h, w)."""
        logits = self.logits(frames_bgr)
        return marking_probability(logits), drivable_probability(logits) if self.has_drivable else None


@lru_cache(maxsize=4)
def load(path: str, threads: int = 1) -> LaneSegModel:
    """One session per (file, threads) per process: lane methods are called frame by frame."""
    return LaneSegModel(path, threads)
