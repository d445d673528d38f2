"""Contact sheets a person can look at to check a dataset (PNG, BGR)."""
from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np

from signlane_data.common import atomic_imwrite
from signlane.label_masks import IGNORE, dataset_encoding, read_mask
from signlane.draw import SHEET_BG as BG, contact_sheet, put_label
from signlane.world.art import SIGN_CLASSES

MASK_BGR = np.array([255, 0, 255], np.float32)  # magenta: unlike any road, sky or sign colour
MASK_ALPHA = 0.55
LINE_BGR = {"left": (255, 160, 0), "right": (0, 140, 255), "center": (0, 255, 255)}
IGNORE_DIM = 0.4  # ignored pixels keep this much of their brightness
HEADER_H = 22


def lane_overlay(image: np.ndarray, ids: np.ndarray, lane: dict | None = None) -> np.ndarray:
    """`image` (uint8 (H, W, 3) BGR) with its label mask `ids` (uint8 (H, W) 0/1/255,
    signlane.label_masks) drawn: marking (1) tinted in semi-transparent magenta, ignored pixels
    (255) darkened, and the label's left/right/center image polylines; returns a new BGR image."""
    out = image.astype(np.float32)
    on = ids == 1
    out[on] = out[on] * (1 - MASK_ALPHA) + MASK_BGR * MASK_ALPHA
    out[ids == IGNORE] *= IGNORE_DIM
    out = out.astype(np.uint8)
    thick = max(1, round(image.shape[1] / 200))  # stays visible when the sheet shrinks the frame
    for key, color in LINE_BGR.items():
        pts = np.asarray((lane or {}).get(key, []), np.float32).reshape(-1, 2)
        if len(pts) >= 2:
            cv2.polylines(out, [np.round(pts * 16).astype(np.int32)], False, color, thick, cv2.LINE_AA, 4)
    return out


def read_jsonl(path: Path, limit: int | None = None, stride: int = 1) -> list[dict]:
    """Every `stride`-th object of a JSON-lines file, at most `limit` of them."""
    rows = []
    with open(path) as f:
        for k, line in enumerate(f):
            if line.strip() and k % stride == 0:
                rows.append(json.loads(line))
            if limit is not None and len(rows) >= limit:
                break
    return rows


def write_lane_preview(out_dir: str | Path, count: int = 32, cols: int = 8,
                       tile: tuple[int, int] = (240, 180), stride: int = 1) -> Path:
    """`preview.png` in a lane/drive dataset: `count` frames (every `stride`-th) with mask and
    polylines, each labelled with its id and teacher steering."""
    out_dir = Path(out_dir)
    tiles, names = [], []
    encoding = dataset_encoding(out_dir)
    for row in read_jsonl(out_dir / "labels.jsonl", count, stride):
        img = cv2.imread(str(out_dir / row["image"]), cv2.IMREAD_COLOR)
        tiles.append(lane_overlay(img, read_mask(out_dir / row["mask"], encoding), row.get("lane")))
        names.append(f"{row['id']} steer {row.get('steering', 0.0):+.2f}")
    path = out_dir / "preview.png"
    atomic_imwrite(path, contact_sheet(tiles, cols, tile, names, gap=0))
    return path


def _spread(items: list, k: int) -> list:
    """Up to k items spread evenly over the list (so both crop sources show up)."""
    if len(items) <= k:
        return items
    return [items[int(j)] for j in np.linspace(0, len(items) - 1, k).round()]


def write_sign_preview(out_dir: str | Path, per_class: int = 16, classes: Sequence[str] = SIGN_CLASSES,
                       tile: tuple[int, int] = (64, 64)) -> Path:
    """`preview.png` in a sign dataset: one row per class, a header with the class name and count
    above `per_class` crops spread over the class folder."""
    out_dir = Path(out_dir)
    width = per_class * tile[0]
    parts = []
    for name in classes:
        files = sorted((out_dir / name).glob("*.png"))
        header = np.full((HEADER_H, width, 3), (70, 50, 30), np.uint8)
        put_label(header, f"{name}  ({len(files)} crops)", (4, HEADER_H - 7), 0.5)
        crops = [cv2.imread(str(p), cv2.IMREAD_COLOR) for p in _spread(files, per_class)]
        row = np.full((tile[1], width, 3), BG, np.uint8)
        if crops:
            sheet = contact_sheet(crops, per_class, tile, gap=0)
            row[:, :sheet.shape[1]] = sheet
        parts += [header, row]
    path = out_dir / "preview.png"
    atomic_imwrite(path, np.vstack(parts))
    return path
