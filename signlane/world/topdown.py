"""Top-down pictures of a track (road, paint, signs, a driven path) for people to look at."""
from __future__ import annotations

import cv2
import numpy as np

from signlane.world.art import SIGN_NAMES
from signlane.world.scene import ASPHALT, SHADOW, Scene

SIGN_BGR = {"stop": (40, 40, 220), "left": (200, 120, 0), "right": (200, 120, 0), "straight": (200, 120, 0),
            "no_left": (60, 60, 200), "no_right": (60, 60, 200)}


def draw_topdown(scene: Scene, px_per_m: float | None = None, path_xy: np.ndarray | None = None,
                 marks: list[tuple[float, float, tuple[int, int, int]]] | None = None) -> np.ndarray:
    """uint8 BGR picture of the scene from above, north up; optional driven path (N,2 world m).
    The default scale makes the longer side about 900 pixels."""
    track = scene.track
    x0, y0, x1, y1 = track.bounds_m(margin=5.0)
    px_per_m = px_per_m or 900.0 / max(x1 - x0, y1 - y0)
    W, H = int((x1 - x0) * px_per_m), int((y1 - y0) * px_per_m)
    img = np.full((H, W, 3), (70, 120, 80), np.uint8)

    def to_px(xy: np.ndarray) -> np.ndarray:
        xy = np.asarray(xy, float).reshape(-1, 2)
        return np.column_stack([(xy[:, 0] - x0) * px_per_m, (y1 - xy[:, 1]) * px_per_m])

    p = scene.paint
    lk = scene.looks
    colour = {ASPHALT: lk.asphalt, 1: lk.white, 2: lk.yellow}
    order = np.argsort([{ASPHALT: 0, SHADOW: 9}.get(int(l), 1) for l in p.layers], kind="stable")
    for k in order:
        layer = int(p.layers[k])
        if layer == SHADOW:
            continue
        poly = np.round(to_px(p.verts[p.starts[k]:p.starts[k + 1]]) * 16).astype(np.int32)
        cv2.fillPoly(img, [poly], colour.get(layer, lk.white), cv2.LINE_AA, 4)
    for obj in scene.objects:
        c = to_px([[obj.x, obj.y]])[0]
        is_sign = obj.kind in SIGN_NAMES
        col = SIGN_BGR.get(obj.kind, (0, 200, 255)) if is_sign else (160, 160, 160)
        r = max(2, int(1.2 * px_per_m)) if is_sign else max(1, int(0.5 * px_per_m))
        cv2.circle(img, tuple(int(v) for v in c), r, col, -1, cv2.LINE_AA)
        if is_sign:
            tip = c + 2.5 * px_per_m * np.array([np.cos(obj.facing), -np.sin(obj.facing)])
            cv2.line(img, tuple(int(v) for v in c), tuple(int(v) for v in tip), col, 1, cv2.LINE_AA)
            cv2.putText(img, obj.kind, (int(c[0]) + r + 1, int(c[1]) - r), cv2.FONT_HERSHEY_SIMPLEX,
                        0.35, (255, 255, 255), 1, cv2.LINE_AA)
    if path_xy is not None and len(path_xy) > 1:
        pts = np.round(to_px(path_xy) * 16).astype(np.int32)
        cv2.polylines(img, [pts], False, (0, 0, 255), 2, cv2.LINE_AA, 4)
        cv2.circle(img, tuple(int(v) for v in to_px(path_xy[:1])[0]), 4, (0, 255, 0), -1)
    for x, y, col in marks or []:
        cv2.drawMarker(img, tuple(int(v) for v in to_px([[x, y]])[0]), col, cv2.MARKER_CROSS, 10, 2)
    return img
