"""Upright barriers (VIA's green rails beside its roads) drawn into the renderer's paint-id image.

Each barrier quad stands on the ground along a base segment and leans outward; quads are culled
by distance, clipped to the camera's near plane in 3-D and filled far to near, after the ground
and before signs (a barrier only ever hides ground farther away than its foot).
"""
from __future__ import annotations

import cv2
import numpy as np

from signlane.camera import Camera

NEAR_M = 0.05  # as the road renderer's
RANGE_M = 60.0


def draw_barriers(ids: np.ndarray, barriers, world_to_ground: np.ndarray, camera: Camera, paint_id: int) -> int:
    """Fill the visible barrier quads into `ids` (uint8 (H, W), in place); returns how many."""
    if len(barriers.base) == 0:
        return 0
    rot, shift = world_to_ground[:2, :2], world_to_ground[:2, 2]
    c = barriers.centers @ rot.T + shift
    dist = np.hypot(c[:, 0], c[:, 1])
    sel = np.nonzero((c[:, 1] > -2.0) & (dist < RANGE_M))[0]
    if len(sel) == 0:
        return 0
    base = barriers.base[sel] @ rot.T + shift  # (Q, 2, 2) ground metres
    lean = barriers.lean[sel] @ rot.T  # a direction: no shift
    top = base + lean[:, None, :]
    z0, z1 = np.zeros(base.shape[:2]), np.full(base.shape[:2], barriers.height_m)
    # quad corners: base start, base end, top end, top start
    quads = np.stack([np.column_stack([base[:, 0], z0[:, 0]]), np.column_stack([base[:, 1], z0[:, 1]]),
                      np.column_stack([top[:, 1], z1[:, 1]]), np.column_stack([top[:, 0], z1[:, 0]])], axis=1)
    R, t = camera.R, camera.t
    cam = quads @ R.T + t  # (Q, 4, 3) camera frame
    order = np.argsort(-dist[sel])
    polys = []
    for q in order:
        pts = cam[q]
        if pts[:, 2].max() <= NEAR_M:
            continue
        if pts[:, 2].min() < NEAR_M:
            pts = _clip_near(pts)
            if len(pts) < 3:
                continue
        uv = pts @ camera.K.T
        pix = uv[:, :2] / uv[:, 2:3]
        polys.append(np.round(np.clip(pix, -1e5, 1e5) * 16).astype(np.int32))
    H, W = ids.shape
    drawn = 0
    for p in polys:
        if p[:, 0].max() < 0 or p[:, 0].min() >= W * 16 or p[:, 1].max() < 0 or p[:, 1].min() >= H * 16:
            continue
        cv2.fillPoly(ids, [p], paint_id, cv2.LINE_8, 4)
        drawn += 1
    return drawn


def _clip_near(pts: np.ndarray) -> np.ndarray:
    """Sutherland-Hodgman clip of a 3-D polygon (camera frame) to depth >= NEAR_M."""
    out = []
    n = len(pts)
    for i in range(n):
        a, b = pts[i], pts[(i + 1) % n]
        ina, inb = a[2] >= NEAR_M, b[2] >= NEAR_M
        if ina:
            out.append(a)
        if ina != inb:
            t = (NEAR_M - a[2]) / (b[2] - a[2])
            out.append(a + t * (b - a))
    return np.array(out)
