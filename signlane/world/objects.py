"""Upright objects (signs on poles, distractors) drawn in perspective with exact pixel masks."""
from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from signlane.camera import Camera
from signlane.world.art import SIGN_NAMES, draw_distractor, draw_sign, random_style
from signlane.world.track import WorldObject

SPRITE_BUCKETS = (16, 32, 64, 128, 256)
POLE_BGR = (120, 120, 125)
BACK_BGR = (150, 150, 155)
DISC_BACK_BGR = (228, 228, 228)
MAX_RANGE_M = 90.0


@dataclass(frozen=True)
class DrawnObject:
    """One object as drawn this frame: its face pixels (absolute image coordinates)."""

    obj: WorldObject
    box_roi: tuple[int, int, int, int]  # x0, y0, x1, y1 of the warped region
    face: np.ndarray  # bool mask within box_roi, face pixels of this object
    distance: float  # metres from the camera, on the ground
    front: bool  # the face (not the back) looks at the camera
    total_px: float  # projected face area in pixels, also outside the image


def sprite_for(cache: dict, obj: WorldObject, px: float, strength: float) -> np.ndarray:
    """BGRA sprite for obj at about px pixels, cached per (kind, seed, bucket)."""
    bucket = next((b for b in SPRITE_BUCKETS if b >= px), SPRITE_BUCKETS[-1])
    key = (obj.kind, obj.seed, bucket)
    if key not in cache:
        rng = np.random.default_rng(obj.seed)
        if obj.kind in SIGN_NAMES:
            cache[key] = draw_sign(obj.kind, bucket, random_style(rng, strength), rng)
        else:
            cache[key] = draw_distractor(obj.kind, bucket, rng)
    return cache[key]


def _corners_world(obj: WorldObject, aspect: float, cam_xy: np.ndarray, ground: bool) -> np.ndarray:
    """Face corners (TL, TR, BR, BL) in 3-D world metres (x, y, z)."""
    if ground:  # cones and boxes: a billboard that turns to the camera
        d = np.array([obj.x, obj.y]) - cam_xy
        facing = math.atan2(-d[1], -d[0])
    else:
        facing = obj.facing
    f = np.array([math.cos(facing), math.sin(facing)])
    right = np.array([-f[1], f[0]])  # viewer's right when looking at the face
    h = obj.size_m
    w = h * aspect
    c = np.array([obj.x, obj.y])
    top, bot = obj.height_m + h / 2, obj.height_m - h / 2
    pts = [(c - right * w / 2, top), (c + right * w / 2, top), (c + right * w / 2, bot), (c - right * w / 2, bot)]
    return np.array([[p[0], p[1], z] for p, z in pts])


def draw_objects(image: np.ndarray, objects: list[WorldObject], camera: Camera, world_to_ground: np.ndarray,
                 cache: dict, strength: float, sign_gain: float = 1.0, disc_backs: bool = False) -> list[DrawnObject]:
    """Draw objects far to near onto image (uint8 BGR, in place); return what was drawn.
    `sign_gain` brightens sign faces (VIA lights them from the car); `disc_backs` draws a sign's
    back as a white disc (VIA's) instead of a grey plate of the face's outline."""
    if not objects:
        return []
    xy = np.array([[o.x, o.y] for o in objects])
    g = xy @ world_to_ground[:2, :2].T + world_to_ground[:2, 2]
    dist = np.hypot(g[:, 0], g[:, 1])
    # in range and within the horizontal field of view (with a margin for the object's width)
    half_fov = math.radians(camera.hfov_deg) / 2 + 0.2
    bearing = np.abs(np.arctan2(g[:, 0], g[:, 1]) - math.radians(camera.yaw_deg))
    order = [i for i in np.argsort(-dist) if g[i, 1] > 0.3 and dist[i] < MAX_RANGE_M
             and bearing[i] < half_fov + 2.0 / max(dist[i], 1.0)]
    cam_xy = np.linalg.solve(world_to_ground[:2, :2], -world_to_ground[:2, 2])
    a = world_to_ground
    drawn = []
    for i in order:
        obj = objects[i]
        ground = obj.kind in ("cone", "box")
        probe = sprite_for(cache, obj, 32, strength)  # billboards and panels are not square
        aspect = probe.shape[1] / probe.shape[0]
        world = _corners_world(obj, aspect, cam_xy, ground)
        gpts = np.column_stack([world[:, :2] @ a[:2, :2].T + a[:2, 2], world[:, 2]])
        pix, depth = camera.project(gpts)
        if np.any(depth < 0.2):
            continue
        size_px = float(np.max(np.ptp(pix, axis=0)))
        if size_px < 1.0:
            continue
        if not ground:
            _draw_pole(image, camera, gpts, obj)
        d = drawn_face(image, obj, pix, size_px, cache, strength, cam_xy, ground,
                       sign_gain if obj.kind in SIGN_NAMES else 1.0, disc_backs and obj.kind in SIGN_NAMES)
        if d is not None:
            drawn.append(DrawnObject(obj, d[0], d[1], float(dist[i]), d[2], d[3]))
    return drawn


def _draw_pole(image: np.ndarray, camera: Camera, face_ground: np.ndarray, obj: WorldObject) -> None:
    base = face_ground[2:4, :2].mean(axis=0)
    bottom_z = face_ground[2, 2]
    w = 0.035  # half of VIA's 0.07 m pole
    fwd = face_ground[1, :2] - face_ground[0, :2]
    fwd = fwd / (np.hypot(*fwd) + 1e-9) * w
    quad = np.array([[*(base - fwd), bottom_z], [*(base + fwd), bottom_z], [*(base + fwd), 0.0], [*(base - fwd), 0.0]])
    pix, depth = camera.project(quad)
    if np.all(depth > 0.2):
        cv2.fillConvexPoly(image, np.round(pix * 16).astype(np.int32), POLE_BGR, cv2.LINE_AA, 4)


def drawn_face(image, obj, pix, size_px, cache, strength, cam_xy, ground, gain=1.0, disc_back=False):
    """Warp the sprite into its projected quad; return (roi, face mask, front, area)."""
    H, W = image.shape[:2]
    x0, y0 = np.floor(pix.min(axis=0)).astype(int)
    x1, y1 = np.ceil(pix.max(axis=0)).astype(int) + 1
    area = float(abs(cv2.contourArea(pix.astype(np.float32))))
    cx0, cy0, cx1, cy1 = max(x0, 0), max(y0, 0), min(x1, W), min(y1, H)
    if cx1 <= cx0 or cy1 <= cy0:
        return None
    to_cam = cam_xy - np.array([obj.x, obj.y])
    front = ground or (math.cos(obj.facing) * to_cam[0] + math.sin(obj.facing) * to_cam[1]) > 0
    sprite = sprite_for(cache, obj, size_px, strength)
    sh, sw = sprite.shape[:2]
    area *= float(np.mean(sprite[:, :, 3] > 127))  # the face, not its square, is what can be cut off
    src = np.array([[0, 0], [sw, 0], [sw, sh], [0, sh]], np.float32)
    dst = (pix - np.array([cx0, cy0])).astype(np.float32)
    if not front:  # the back of a sign: a plain plate of the same outline, or VIA's white disc
        src = src[[1, 0, 3, 2]]
        if disc_back:
            sprite = _disc_sprite(sh)
    M = cv2.getPerspectiveTransform(src, dst)
    warped = cv2.warpPerspective(sprite, M, (cx1 - cx0, cy1 - cy0), flags=cv2.INTER_LINEAR,
                                 borderMode=cv2.BORDER_CONSTANT, borderValue=(0, 0, 0, 0))
    alpha = warped[:, :, 3:4].astype(np.float32) * (1.0 / 255.0)
    roi = image[cy0:cy1, cx0:cx1]
    if front:
        color = warped[:, :, :3] if gain == 1.0 else cv2.convertScaleAbs(warped[:, :, :3], alpha=gain)
    else:
        color = np.full_like(warped[:, :, :3], DISC_BACK_BGR if disc_back else BACK_BGR)
    roi[:] = (roi * (1.0 - alpha) + color * alpha + 0.5).astype(np.uint8)
    return (cx0, cy0, cx1, cy1), warped[:, :, 3] > 127, front, area


_DISCS: dict[int, np.ndarray] = {}


def _disc_sprite(size: int) -> np.ndarray:
    """BGRA white disc filling a size x size square (the back of VIA's signs)."""
    if size not in _DISCS:
        big = np.zeros((size * 4, size * 4), np.uint8)
        cv2.circle(big, (size * 2, size * 2), size * 2 - 2, 255, -1, cv2.LINE_AA)
        a = cv2.resize(big, (size, size), interpolation=cv2.INTER_AREA)
        _DISCS[size] = np.dstack([np.full((size, size, 3), 255, np.uint8), a])
    return _DISCS[size]
