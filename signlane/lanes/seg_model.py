"""Lane-marking segmentation model runtime: the ONNX session with its contract, and the one
pre- and post-processing that training, export parity, evaluation and the runtime all call.

The model takes whole frames resized to its input size (any aspect: a 16:9 frame is squeezed
like it was in training) and returns class logits (N, 2, h, w) for background / lane marking
at its output size; `marking_probability` turns them into P(marking) at that size.
"""
from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import cv2
import numpy as np

from signlane.label_masks import IGNORE
from signlane.onnx_model import InputSpec, ModelError, OnnxModel, prepare_input

TASK = "lane-segmentation"
CLASSES = ("background", "lane_marking")
DEFAULT_MODEL = Path(__file__).resolve().parent.parent / "models" / "lanes.onnx"
DEFAULT_SPEC = InputSpec(160, 120, "RGB", "NCHW", 1.0 / 255.0, (0.45, 0.45, 0.45), (0.25, 0.25, 0.25))
MASK_THRESHOLD = 0.5


def preprocess_frames(frames_bgr: list[np.ndarray], spec: InputSpec = DEFAULT_SPEC) -> np.ndarray:
    """uint8 BGR frames (H, W, 3), any size -> float32 (N, 3, spec.height, spec.width) input."""
    return prepare_input(frames_bgr, spec, "frame")


def marking_probability(logits: np.ndarray) -> np.ndarray:
    """(N, 2, h, w) logits -> float32 (N, h, w) P(lane marking) (the 2-class softmax)."""
    d = np.clip(logits[:, 1] - logits[:, 0], -60.0, 60.0)
    return (1.0 / (1.0 + np.exp(-d))).astype(np.float32)


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


def to_frame_mask(prob: np.ndarray, width: int, height: int, threshold: float = MASK_THRESHOLD) -> np.ndarray:
    """float32 (h, w) P(marking) -> uint8 (height, width) 0/255 mask at the frame's size."""
    up = cv2.resize(prob, (width, height), interpolation=cv2.INTER_LINEAR)
    return (up > threshold).astype(np.uint8) * 255


class LaneSegModel:
    """The segmentation model with its contract read from the ONNX metadata."""

    def __init__(self, path: str | Path = DEFAULT_MODEL, threads: int = 1):
        self.model = OnnxModel(path, TASK, threads, output_rank=4)
        if tuple(self.model.classes) != CLASSES:
            raise ModelError(f"{path}: classes {self.model.classes} are not {list(CLASSES)}")
        self.spec = self.model.input

    def probabilities(self, frames_bgr: list[np.ndarray]) -> np.ndarray:
        """float32 (N, h, w) P(lane marking) at the model's output size."""
        logits = self.model.run(preprocess_frames(frames_bgr, self.spec))
        if logits.ndim != 4 or logits.shape[1] != len(CLASSES):
            raise ModelError(f"{self.model.path}: output shape {logits.shape} is not (N, 2, h, w)")
        return marking_probability(logits)


@lru_cache(maxsize=4)
def load(path: str, threads: int = 1) -> LaneSegModel:
    """One session per (file, threads) per process: lane methods are called frame by frame."""
    return LaneSegModel(path, threads)
