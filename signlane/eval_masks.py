"""Lane-marking mask scores: precision, recall and F1 with a pixel tolerance, at the frame's size.

A predicted pixel is correct when a true marking pixel lies within `tol` pixels of it (a disk),
and a true pixel is found when a predicted one lies within `tol` of it (the usual boundary-style
tolerance: a line one or two pixels off is still the line). Counts are summed over frames.
Pixels without a label (a dataset's 255s, signlane.label_masks) count nowhere: a prediction
there is neither right nor wrong. `iou` is the exact pixel IoU (no tolerance) over the labelled
pixels. A road model (seg_model.ROAD_CLASSES) on a set with road masks (`drivable/<id>.png`,
gen lanes --drivable) is also scored on the road surface: `drivable_iou`, exact pixel IoU.
The marking mask scored is the one `infer --save-masks` writes for segnet: the model's map brought
up to the frame, sharpened on the frame's own pixels where one output cell spans 3 or more of
them (lanes/sharp_marking.py).
`recall_by_contrast` splits the labelled paint by how far it stands out of the ground around it
in the image (ContrastRecall): what a model misses can be paint nobody could see (night, fog,
glare), or paint it should have found.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
from tqdm import tqdm

from signlane.label_masks import IGNORE, dataset_encoding, read_mask
from signlane.paint_visibility import paint_contrast


@dataclass
class MaskCounts:
    tp_pred: int = 0  # predicted pixels near a true one
    pred: int = 0
    tp_true: int = 0  # true pixels near a predicted one
    true: int = 0
    frames: int = 0
    inter: int = 0  # exact pixels: predicted and true
    union: int = 0  # predicted or true (labelled pixels only)

    def add(self, pred: np.ndarray, true: np.ndarray, tol: int = 2, ignore: np.ndarray | None = None) -> np.ndarray:
        """pred, true: uint8 or bool (H, W), nonzero = marking; ignore: bool (H, W) pixels
        without a label, or None (every pixel labelled). -> bool (H, W): the true pixels found."""
        k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * tol + 1, 2 * tol + 1))
        p, t = pred > 0, true > 0
        if ignore is not None:
            p, t = p & ~ignore, t & ~ignore
        self.inter += int(np.count_nonzero(p & t))
        self.union += int(np.count_nonzero(p | t))
        self.tp_pred += int(np.count_nonzero(p & (cv2.dilate(t.astype(np.uint8), k) > 0)))
        found = t & (cv2.dilate(p.astype(np.uint8), k) > 0)
        self.tp_true += int(np.count_nonzero(found))
        self.pred += int(np.count_nonzero(p))
        self.true += int(np.count_nonzero(t))
        self.frames += 1
        return found

    def summary(self) -> dict:
        precision = self.tp_pred / max(self.pred, 1)
        recall = self.tp_true / max(self.true, 1)
        f1 = 2 * precision * recall / max(precision + recall, 1e-12)
        return {"frames": self.frames, "precision": precision, "recall": recall, "f1": f1}

    @property
    def iou(self) -> float:
        return self.inter / max(self.union, 1)


CONTRAST_EDGES = (0, 4, 8, 16, 32, 64, 256)  # paint contrast bins, CIELAB distance levels (paint_visibility)


@dataclass
class ContrastRecall:
    """Labelled paint pixels, and those found (within the tolerance), by their contrast against
    the labelled ground beside them (signlane.paint_visibility.paint_contrast). Under about 4
    levels the paint cannot be told from the road in the image at all (sets made since that rule
    leave such paint unlabelled)."""

    paint: np.ndarray = field(default_factory=lambda: np.zeros(len(CONTRAST_EDGES) - 1, np.int64))
    found: np.ndarray = field(default_factory=lambda: np.zeros(len(CONTRAST_EDGES) - 1, np.int64))

    def add(self, image_bgr: np.ndarray, true_ids: np.ndarray, found: np.ndarray) -> None:
        """true_ids: uint8 (H, W) 0/1/255; found: bool (H, W), the true pixels found."""
        contrast = paint_contrast(image_bgr, true_ids == 1, true_ids == 0)
        paint = ~np.isnan(contrast)  # (paint with no ground beside it: no contrast to measure)
        bins = np.clip(np.searchsorted(CONTRAST_EDGES, contrast[paint], side="right") - 1, 0, len(self.paint) - 1)
        self.paint += np.bincount(bins, minlength=len(self.paint))
        self.found += np.bincount(bins, weights=found[paint], minlength=len(self.paint)).astype(np.int64)

    def rows(self) -> list[dict]:
        """Per contrast bin: its share of the paint, its recall, and its share of the paint missed."""
        missed = self.paint - self.found
        return [{"contrast": f"{lo}-{hi}", "paint_share": int(n) / max(int(self.paint.sum()), 1),
                 "recall": int(f) / max(int(n), 1), "missed_share": int(m) / max(int(missed.sum()), 1)}
                for lo, hi, n, f, m in zip(CONTRAST_EDGES[:-1], CONTRAST_EDGES[1:], self.paint, self.found, missed)]


@dataclass
class RoadCounts:
    """Exact pixel IoU of a road-surface mask, summed over frames; ids 255 count nowhere."""

    inter: int = 0
    union: int = 0
    frames: int = 0

    def add(self, pred: np.ndarray, true_ids: np.ndarray) -> None:
        """pred: uint8 or bool (H, W), nonzero = road; true_ids: uint8 (H, W) 0/1/255."""
        known = true_ids != IGNORE
        p, t = (pred > 0) & known, true_ids == 1
        self.inter += int(np.count_nonzero(p & t))
        self.union += int(np.count_nonzero(p | t))
        self.frames += 1

    @property
    def iou(self) -> float:
        return self.inter / max(self.union, 1)


def eval_masks(data: str | Path, model: str | Path | None = None, tol: int = 2, threads: int = 2,
               progress: bool = True) -> dict:
    """The segmentation model's marking F1 within `tol` px, and exact IoU, on a lane dataset
    folder (labels.jsonl with images/ and masks/, e.g. a fresh `signlane gen lanes --seed S`),
    in either mask encoding (signlane.label_masks); pixels without a label count nowhere."""
    from signlane.lanes.seg_model import DEFAULT_MODEL, LaneSegModel, to_frame_mask
    from signlane.lanes.sharp_marking import sharpen_marking
    seg = LaneSegModel(model or DEFAULT_MODEL, threads)
    root = Path(data)
    labels = root / "labels.jsonl"
    if not labels.is_file():
        raise ValueError(f"{root}: no labels.jsonl (not a lane dataset)")
    encoding = dataset_encoding(root)
    counts, road, contrast = MaskCounts(), RoadCounts(), ContrastRecall()
    recs = [json.loads(line) for line in labels.read_text().splitlines() if line.strip()]
    for rec in tqdm(recs, desc="eval masks", unit="frame", disable=not progress):
        img = cv2.imread(str(root / rec["image"]), cv2.IMREAD_COLOR)
        if img is None:
            raise ValueError(f"{root / rec['image']}: unreadable image")
        true = read_mask(root / rec["mask"], encoding)
        if true.shape != img.shape[:2]:
            raise ValueError(f"{root / rec['mask']}: mask {true.shape} is not the image's size {img.shape[:2]}")
        marking, drivable = seg.maps([img])
        h, w = img.shape[:2]
        # the mask infer --save-masks writes for segnet
        pred = sharpen_marking(to_frame_mask(marking[0], w, h), img, (marking.shape[2], marking.shape[1]))
        found = counts.add(pred, true == 1, tol, true == IGNORE)
        contrast.add(img, true, found)
        if drivable is not None and rec.get("drivable"):
            road_true = read_mask(root / rec["drivable"], encoding)
            road.add(to_frame_mask(drivable[0], w, h), road_true)
    out = {"model": str(model or DEFAULT_MODEL), "data": str(root), "mask_encoding": encoding, "tolerance_px": tol,
           **counts.summary(), "iou": counts.iou, "recall_by_contrast": contrast.rows()}
    if road.frames:
        out.update({"drivable_iou": road.iou, "drivable_frames": road.frames})
    return out
