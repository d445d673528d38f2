"""Overlays for people: lane polylines, masks, sign boxes, a HUD, outlined labels, contact sheets
(charts: signlane/plots.py; video files: signlane/video_out.py).

All functions take and return uint8 (H, W, 3) BGR images; drawing functions work in place and
also return the image for chaining.
"""
from __future__ import annotations

from pathlib import Path
from typing import Iterable, Sequence

import cv2
import numpy as np

from signlane.fileio import atomic_imwrite

LEFT_BGR, RIGHT_BGR, CENTER_BGR = (255, 120, 0), (0, 200, 0), (0, 230, 255)
MASK_BGR = (255, 0, 255)
SIGN_BOX_BGR = {"stop": (0, 0, 255), "unknown": (160, 160, 160)}
DEFAULT_BOX_BGR = (255, 0, 200)


def overlay_mask(image: np.ndarray, mask: np.ndarray, color=MASK_BGR, alpha: float = 0.5) -> np.ndarray:
    """Tint pixels where mask (H, W, any dtype) is non-zero."""
    m = mask > 0
    if m.any():
        image[m] = (image[m] * (1 - alpha) + np.array(color, np.float32) * alpha).astype(np.uint8)
    return image


def draw_polyline(image: np.ndarray, pts: np.ndarray | None, color, thickness: int = 2) -> np.ndarray:
    if pts is not None and len(pts) > 1:
        p = np.round(np.asarray(pts, np.float64) * 16).astype(np.int32)
        cv2.polylines(image, [p], False, color, thickness, cv2.LINE_AA, 4)
    return image


def draw_lane(image: np.ndarray, left=None, right=None, center=None, thickness: int = 2) -> np.ndarray:
    draw_polyline(image, left, LEFT_BGR, thickness)
    draw_polyline(image, right, RIGHT_BGR, thickness)
    draw_polyline(image, center, CENTER_BGR, max(1, thickness - 1))
    return image


def draw_boxes(image: np.ndarray, boxes: Iterable[tuple[str, float | None, Sequence[int]]]) -> np.ndarray:
    """boxes: (label, score or None, (x, y, w, h)) each."""
    for label, score, (x, y, w, h) in boxes:
        col = SIGN_BOX_BGR.get(label, DEFAULT_BOX_BGR)
        cv2.rectangle(image, (int(x), int(y)), (int(x + w), int(y + h)), col, 1, cv2.LINE_AA)
        text = label if score is None else f"{label} {score:.2f}"
        cv2.putText(image, text, (int(x), max(8, int(y) - 3)), cv2.FONT_HERSHEY_SIMPLEX, 0.35, col, 1, cv2.LINE_AA)
    return image


def draw_hud(image: np.ndarray, lines: Sequence[str], origin=(4, 4)) -> np.ndarray:
    """Text lines on a dark translucent panel at the top-left."""
    if not lines:
        return image
    scale = max(0.35, image.shape[1] / 1280)
    lh = int(22 * scale / 0.5) // 2 + 2
    w = int(max(cv2.getTextSize(t, cv2.FONT_HERSHEY_SIMPLEX, scale, 1)[0][0] for t in lines)) + 8
    x0, y0 = origin
    h = lh * len(lines) + 6
    roi = image[y0:y0 + h, x0:x0 + w]
    roi[:] = (roi * 0.45).astype(np.uint8)
    for i, t in enumerate(lines):
        cv2.putText(image, t, (x0 + 4, y0 + lh * (i + 1)), cv2.FONT_HERSHEY_SIMPLEX, scale, (255, 255, 255), 1,
                    cv2.LINE_AA)
    return image


SHEET_BG = (40, 40, 40)  # BGR background of contact sheets


def put_label(image: np.ndarray, text: str, org: tuple[int, int], scale: float = 0.4) -> np.ndarray:
    """White text with a black outline, readable on any picture (in place)."""
    cv2.putText(image, text, org, cv2.FONT_HERSHEY_SIMPLEX, scale, (0, 0, 0), 3, cv2.LINE_AA)
    cv2.putText(image, text, org, cv2.FONT_HERSHEY_SIMPLEX, scale, (255, 255, 255), 1, cv2.LINE_AA)
    return image


def contact_sheet(images: Sequence[np.ndarray], cols: int = 4, tile: tuple[int, int] | None = None,
                  captions: Sequence[str] | None = None, gap: int = 2, scale: float = 0.35,
                  band: bool = False) -> np.ndarray:
    """The one contact sheet: images (uint8 grey or BGR, any sizes) row by row, each fitted into
    a (w, h) tile (default the first image's size) without distortion (letterboxed; small crops
    enlarged with nearest, so the real pixels show). Captions (one line per '\\n') go on each
    tile's bottom in outlined text, or with band=True on a strip below it (small crops, where text
    over the image would hide it). BGR uint8."""
    if not images:
        raise ValueError("contact_sheet needs at least one image")
    tw, th = tile or (images[0].shape[1], images[0].shape[0])
    cols = max(1, min(cols, len(images)))
    rows = (len(images) + cols - 1) // cols
    texts = [str(captions[i]).split("\n") if captions is not None and i < len(captions) and captions[i] else []
             for i in range(len(images))]
    lh = int(22 * scale / 0.5) + 2
    extra = (max(len(t) for t in texts) * lh + 4) if band and any(texts) else 0
    ch = th + extra
    sheet = np.full((rows * (ch + gap) + gap, cols * (tw + gap) + gap, 3), SHEET_BG, np.uint8)
    for i, im in enumerate(images):
        r, c = divmod(i, cols)
        y, x = gap + r * (ch + gap), gap + c * (tw + gap)
        sheet[y:y + th, x:x + tw] = _fit(im, (tw, th))
        lines = texts[i]
        for k, text in enumerate(lines):
            if extra:  # on the band: plain white on the sheet's dark background
                cv2.putText(sheet, text, (x + 2, y + th + (k + 1) * lh), cv2.FONT_HERSHEY_SIMPLEX, scale,
                            (255, 255, 255), 1, cv2.LINE_AA)
            else:
                put_label(sheet, text, (x + 3, y + th - 5 - (len(lines) - 1 - k) * lh), scale)
    return sheet


def _fit(img: np.ndarray, tile: tuple[int, int]) -> np.ndarray:
    tw, th = tile
    if img.ndim == 2:
        img = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
    h, w = img.shape[:2]
    k = min(tw / w, th / h)
    nw, nh = max(1, round(w * k)), max(1, round(h * k))
    out = np.full((th, tw, 3), SHEET_BG, np.uint8)
    y0, x0 = (th - nh) // 2, (tw - nw) // 2
    out[y0:y0 + nh, x0:x0 + nw] = cv2.resize(img, (nw, nh), interpolation=cv2.INTER_AREA if k < 1 else cv2.INTER_NEAREST)
    return out


def write_image(path: str | Path, image: np.ndarray) -> None:
    """Write an image atomically (temp name in the same folder, then rename)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_imwrite(path if path.suffix else path.with_suffix(".png"), image)
