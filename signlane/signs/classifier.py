"""Sign classifier runtime: ONNX model + the one crop preprocessing used everywhere.

`preprocess_crops` is the only place crops become model input: training, export parity,
evaluation and the runtime all call it, with the InputSpec read from the model's metadata.
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from signlane.onnx_model import InputSpec, ModelError, OnnxModel, prepare_input
from signlane.types import SignDetection

TASK = "sign-classifier"
DEFAULT_MODEL = Path(__file__).resolve().parent.parent / "models" / "signs.onnx"
DEFAULT_SPEC = InputSpec(32, 32, "RGB", "NCHW", 1.0 / 255.0, (0.5, 0.5, 0.5), (0.25, 0.25, 0.25))


def crop(image_bgr: np.ndarray, box: tuple[int, int, int, int]) -> np.ndarray:
    """The pixels of box (x, y, w, h), clipped to the image; uint8 (h, w, 3) BGR."""
    x, y, w, h = (int(v) for v in box)
    H, W = image_bgr.shape[:2]
    x0, y0, x1, y1 = max(0, x), max(0, y), min(W, x + w), min(H, y + h)
    if x1 <= x0 or y1 <= y0:
        raise ValueError(f"box {box} lies outside the {W}x{H} image")
    return image_bgr[y0:y1, x0:x1]


def preprocess_crops(crops_bgr: list[np.ndarray], spec: InputSpec = DEFAULT_SPEC) -> np.ndarray:
    """uint8 BGR crops of any size -> float32 (N, 3, spec.height, spec.width) normalised input."""
    return prepare_input(crops_bgr, spec, "crop")


def softmax(logits: np.ndarray) -> np.ndarray:
    z = logits - logits.max(axis=1, keepdims=True)
    e = np.exp(z)
    return e / e.sum(axis=1, keepdims=True)


class SignClassifier:
    """Classifies crops with an ONNX model whose classes and preprocessing come from its metadata."""

    def __init__(self, path: str | Path = DEFAULT_MODEL, threads: int = 1, batch: int = 32):
        self.model = OnnxModel(path, TASK, threads)
        if "unknown" not in self.model.classes:
            raise ModelError(f"{path}: classes {self.model.classes} lack 'unknown' (the not-a-sign class)")
        self.classes = self.model.classes
        self.batch = batch

    def probabilities(self, crops_bgr: list[np.ndarray]) -> np.ndarray:
        """(N, len(classes)) float32 class probabilities."""
        if not crops_bgr:
            return np.zeros((0, len(self.classes)), np.float32)
        parts = []
        for i in range(0, len(crops_bgr), self.batch):
            x = preprocess_crops(crops_bgr[i:i + self.batch], self.model.input)
            parts.append(softmax(self.model.run(x)))
        return np.concatenate(parts).astype(np.float32)

    def classify(self, crops_bgr: list[np.ndarray]) -> list[tuple[str, float, dict[str, float]]]:
        """(label, score, {label: p}) per crop."""
        probs = self.probabilities(crops_bgr)
        out = []
        for p in probs:
            k = int(np.argmax(p))
            out.append((self.classes[k], float(p[k]), {c: float(v) for c, v in zip(self.classes, p)}))
        return out

    def label_detections(self, image_bgr: np.ndarray, proposals: list[SignDetection],
                         min_score: float = 0.5, verdict=None) -> list[SignDetection]:
        """Proposals relabelled by the classifier; 'unknown' and low-score ones dropped.
        `verdict(proposal, label, score)`, when given, hears every proposal's verdict."""
        if not proposals:
            return []
        results = self.classify([crop(image_bgr, p.box) for p in proposals])
        if verdict is not None:
            for p, (label, score, _) in zip(proposals, results):
                verdict(p, label, score)
        return [replace(p, label=label, score=score) for p, (label, score, _) in zip(proposals, results)
                if label != "unknown" and score >= min_score]
