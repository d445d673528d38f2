"""Overlays for people: lane polylines, masks, sign boxes, a HUD, contact sheets, bar charts
(video files: signlane/video_out.py).

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


def contact_sheet(images: Sequence[np.ndarray], cols: int = 4, tile: tuple[int, int] | None = None,
                  captions: Sequence[str] | None = None, gap: int = 2) -> np.ndarray:
    """Grid of images (resized to `tile` (w, h), default the first image's size), BGR uint8."""
    if not images:
        raise ValueError("contact_sheet needs at least one image")
    tw, th = tile or (images[0].shape[1], images[0].shape[0])
    rows = (len(images) + cols - 1) // cols
    sheet = np.full((rows * (th + gap) + gap, cols * (tw + gap) + gap, 3), 30, np.uint8)
    for i, im in enumerate(images):
        if im.ndim == 2:
            im = cv2.cvtColor(im, cv2.COLOR_GRAY2BGR)
        r, c = divmod(i, cols)
        y, x = gap + r * (th + gap), gap + c * (tw + gap)
        sheet[y:y + th, x:x + tw] = cv2.resize(im, (tw, th), interpolation=cv2.INTER_AREA)
        if captions:
            cv2.putText(sheet, captions[i], (x + 3, y + th - 5), cv2.FONT_HERSHEY_SIMPLEX, 0.35, (255, 255, 255), 1,
                        cv2.LINE_AA)
    return sheet


def write_image(path: str | Path, image: np.ndarray) -> None:
    """Write an image atomically (temp name in the same folder, then rename)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_imwrite(path if path.suffix else path.with_suffix(".png"), image)


def bar_chart(title: str, labels: Sequence[str], series: dict[str, Sequence[float]], ymax: float | None = None,
              size: tuple[int, int] = (900, 420)) -> np.ndarray:
    """A grouped bar chart (one group per label, one bar per series) as a BGR image."""
    W, H = size
    img = np.full((H, W, 3), 255, np.uint8)
    left, bottom, top = 60, 70, 40
    vals = [v for s in series.values() for v in s if np.isfinite(v)]
    ymax = ymax or (max(vals) * 1.15 if vals else 1.0) or 1.0
    cv2.putText(img, title, (left, 25), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (0, 0, 0), 1, cv2.LINE_AA)
    for k in range(5):  # y grid and ticks
        v = ymax * k / 4
        y = int(H - bottom - (H - bottom - top) * k / 4)
        cv2.line(img, (left, y), (W - 10, y), (225, 225, 225), 1)
        cv2.putText(img, f"{v:.3g}", (5, y + 4), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (80, 80, 80), 1, cv2.LINE_AA)
    palette = [(200, 120, 30), (40, 160, 240), (60, 180, 60), (180, 60, 180), (60, 60, 220)]
    gw = (W - left - 10) / max(len(labels), 1)
    bw = gw * 0.8 / max(len(series), 1)
    for i, lab in enumerate(labels):
        x0 = left + i * gw + gw * 0.1
        for j, (name, vs) in enumerate(series.items()):
            v = vs[i]
            if not np.isfinite(v):
                continue
            h = (H - bottom - top) * min(v, ymax) / ymax
            cv2.rectangle(img, (int(x0 + j * bw), int(H - bottom - h)), (int(x0 + (j + 1) * bw) - 2, H - bottom),
                          palette[j % len(palette)], -1)
        # labels wider than their group wrap onto a second line at ':' (method:variant)
        fit = max(4, int(gw * 0.8 / 7))
        for k, part in enumerate(lab.replace(":", "\n:").split("\n")[:2]):
            cv2.putText(img, part[:fit], (int(x0), H - bottom + 18 + 14 * k), cv2.FONT_HERSHEY_SIMPLEX, 0.4,
                        (0, 0, 0), 1, cv2.LINE_AA)
    for j, name in enumerate(series):  # legend
        y = H - 25
        x = left + j * 200
        cv2.rectangle(img, (x, y - 10), (x + 12, y + 2), palette[j % len(palette)], -1)
        cv2.putText(img, name, (x + 18, y), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 1, cv2.LINE_AA)
    return img
