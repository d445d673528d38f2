"""Pinhole camera on a car: image <-> ground-plane homographies and the bird's-eye warp.

Frames used here (all right-handed):
- ground (car) frame, metres: x to the car's right, y forward, z up; origin on the ground
  below the camera.
- camera frame (OpenCV): X right, Y down, Z along the optical axis.
- image: pixels, origin top-left, x right, y down.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import cached_property, lru_cache

import cv2
import numpy as np


@dataclass(frozen=True)
class Camera:
    """A forward camera mounted on a car.

    `pitch_deg` > 0 tilts the camera down towards the road; `roll_deg` > 0 rotates the image
    clockwise as the viewer sees it (the camera's right side dips); `yaw_deg` > 0 turns it right.
    """

    width: int = 320
    height: int = 240
    hfov_deg: float = 90.0
    height_m: float = 1.3
    pitch_deg: float = 10.0
    roll_deg: float = 0.0
    yaw_deg: float = 0.0

    def with_size(self, width: int, height: int) -> "Camera":
        return replace(self, width=width, height=height)

    @cached_property
    def focal_px(self) -> float:
        return (self.width / 2.0) / math.tan(math.radians(self.hfov_deg) / 2.0)

    @cached_property
    def K(self) -> np.ndarray:
        f = self.focal_px
        return np.array([[f, 0.0, self.width / 2.0], [0.0, f, self.height / 2.0], [0.0, 0.0, 1.0]])

    @cached_property
    def R(self) -> np.ndarray:
        """Rotation taking ground-frame vectors (x right, y fwd, z up) to camera-frame vectors."""
        base = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])  # level camera
        p, r, y = (math.radians(a) for a in (self.pitch_deg, self.roll_deg, self.yaw_deg))
        # yaw about ground z (turning right = negative rotation about z-up)
        cy, sy = math.cos(-y), math.sin(-y)
        yaw = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
        # pitch down: rotate about camera X so the optical axis dips
        cp, sp = math.cos(p), math.sin(p)
        pitch = np.array([[1.0, 0.0, 0.0], [0.0, cp, -sp], [0.0, sp, cp]])
        # roll about the optical axis
        cr, sr = math.cos(r), math.sin(r)
        roll = np.array([[cr, -sr, 0.0], [sr, cr, 0.0], [0.0, 0.0, 1.0]])
        return roll @ pitch @ base @ yaw.T

    @cached_property
    def t(self) -> np.ndarray:
        """Translation of the ground origin in camera coordinates (camera sits at z=height_m)."""
        return -self.R @ np.array([0.0, 0.0, self.height_m])

    # --- projections -----------------------------------------------------------------
    def ground_to_image_h(self) -> np.ndarray:
        """3x3 homography mapping ground (x_right_m, y_fwd_m, 1) to image pixels."""
        return self._g2i

    def image_to_ground_h(self) -> np.ndarray:
        return self._i2g

    @cached_property
    def _g2i(self) -> np.ndarray:
        R, t = self.R, self.t
        return self.K @ np.column_stack([R[:, 0], R[:, 1], t])

    @cached_property
    def _i2g(self) -> np.ndarray:
        return np.linalg.inv(self._g2i)

    def project(self, points_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Project 3-D ground-frame points (N,3 float, metres) to pixels.

        Returns (pixels (N,2) float64, depth (N,) metres along the optical axis); points with
        depth <= 0 are behind the camera and their pixels are meaningless.
        """
        pts = np.asarray(points_m, dtype=np.float64).reshape(-1, 3)
        cam = pts @ self.R.T + self.t
        depth = cam[:, 2]
        safe = np.where(np.abs(depth) < 1e-9, 1e-9, depth)
        uv = cam @ self.K.T
        return uv[:, :2] / safe[:, None], depth

    def ground_to_image(self, ground_xy_m: np.ndarray) -> np.ndarray:
        """(N,2) ground metres -> (N,2) pixels (only meaningful in front of the camera)."""
        g = np.asarray(ground_xy_m, dtype=np.float64).reshape(-1, 2)
        pix, _ = self.project(np.column_stack([g, np.zeros(len(g))]))
        return pix

    def image_to_ground(self, pixels: np.ndarray) -> np.ndarray:
        """(N,2) pixels -> (N,2) ground metres; pixels at or above the horizon give NaN."""
        p = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
        h = np.column_stack([p, np.ones(len(p))]) @ self.image_to_ground_h().T
        w = h[:, 2:3]
        out = h[:, :2] / np.where(np.abs(w) < 1e-12, 1e-12, w)
        # a pixel sees the ground only if its viewing ray points down
        rays = np.column_stack([p, np.ones(len(p))]) @ np.linalg.inv(self.K).T
        down = (rays @ self.R)[:, 2] < 0
        out[~down] = np.nan
        return out

    def horizon(self) -> tuple[np.ndarray, float]:
        """Horizon line as (normal n (2,), offset c): pixels with n.x + c > 0 see the ground."""
        # a pixel ray d_cam = K^-1 (u,v,1); it points down when (R^T d)_z < 0
        a = self.R @ np.array([0.0, 0.0, -1.0])  # 'down' in camera coordinates
        row = a @ np.linalg.inv(self.K)  # coefficients on (u, v, 1)
        return row[:2].copy(), float(row[2])

    def ground_mask(self, margin_px: float = 0.0) -> np.ndarray:
        """(H,W) bool, read-only: pixels whose rays hit the ground (below the horizon by margin_px).
        Cached per camera: it depends on nothing else."""
        return _ground_mask(self, float(margin_px))

    def _ground_mask(self, margin_px: float) -> np.ndarray:
        n, c = self.horizon()
        norm = float(np.hypot(*n)) or 1.0
        u = np.arange(self.width) + 0.5
        v = np.arange(self.height) + 0.5
        val = (n[0] * u[None, :] + n[1] * v[:, None] + c) / norm
        mask = val > margin_px
        mask.flags.writeable = False
        return mask

    # --- bird's-eye view -----------------------------------------------------------------
    def birdseye(self, size: tuple[int, int], x_range_m: tuple[float, float],
                 y_range_m: tuple[float, float]) -> "BirdsEye":
        """Bird's-eye warp covering ground x in x_range_m and y (forward) in y_range_m.

        size = (width, height) of the bird's-eye image; its top row is the far edge.
        """
        return BirdsEye(self, size, x_range_m, y_range_m)

    def default_birdseye(self, scale: float = 1.0) -> "BirdsEye":
        """A bird's-eye view that covers what the camera sees of the road ahead: from the
        nearest visible ground row to ~6x that distance, about 3 lane widths across."""
        near = self.image_to_ground(np.array([[self.width / 2, self.height - 1]]))[0]
        y0 = float(near[1]) if np.isfinite(near[1]) else 2.0
        y1 = max(y0 * 6.0, y0 + 8.0)
        half = max(6.0, (y1 - y0) * 0.3)
        w = int(round(self.width * scale))
        h = int(round(self.height * scale))
        return self.birdseye((w, h), (-half, half), (y0, y1))


# VIA's camera (../shared/VIA.md, section 3): 640x480, vertical field of view 60 degrees, mounted
# 2.94 m up and pitched 10.86 degrees down on a body that rests slightly nose-down, so in effect
# 2.9 m above the road at 11.8 degrees (horizon near row 155, the bottom row 3.3 m ahead)
VIA_VFOV_DEG = 60.0
VIA_HEIGHT_M = 2.9
VIA_PITCH_DEG = 11.8
VIA_CAMERA_FORWARD_M = 0.1  # ahead of the car's origin
VIA_WHEELBASE_M = 1.957  # the car's origin is midway along it
# what the car steers about (its rear axle) to the camera: VIA's car turns about a point this far
# behind what its camera measures from
VIA_CAMERA_AHEAD_OF_AXLE_M = VIA_CAMERA_FORWARD_M + VIA_WHEELBASE_M / 2


def hfov_for_vfov(vfov_deg: float, width: int, height: int) -> float:
    return math.degrees(2 * math.atan(math.tan(math.radians(vfov_deg) / 2) * width / height))


def via_camera(width: int = 640, height: int = 480) -> Camera:
    """VIA's camera at a frame size (its vertical field of view is fixed, as in Unity)."""
    return Camera(width, height, hfov_for_vfov(VIA_VFOV_DEG, width, height), VIA_HEIGHT_M, VIA_PITCH_DEG)


@lru_cache(maxsize=64)
def _ground_mask(camera: Camera, margin_px: float) -> np.ndarray:
    return camera._ground_mask(margin_px)


def row_spans(seen: np.ndarray) -> tuple[list[bool], list[int], list[int], bool]:
    """Per row of a bool (h, w) mask of seen ground: whether any is seen, the first and the last
    seen column (0 and w - 1 where none), and whether every row sees one unbroken span (a
    bird's-eye view's footprint of the camera is convex, so it does: a seen column is then told
    by the span's ends)."""
    w = seen.shape[1]
    any_seen = seen.any(axis=1).tolist()
    first = seen.argmax(axis=1).tolist()
    last = (w - 1 - seen[:, ::-1].argmax(axis=1)).tolist()
    spans = bool(np.array_equal(seen.sum(axis=1), np.where(any_seen, np.subtract(last, first) + 1, 0)))
    return any_seen, first, last, spans


@lru_cache(maxsize=32)
def _visible(bev: "BirdsEye") -> np.ndarray:
    cam = bev.camera
    mask = bev.warp(np.full((cam.height, cam.width), 255, np.uint8), cv2.INTER_NEAREST)
    mask.setflags(write=False)  # shared by every caller
    return mask


@dataclass(frozen=True)
class BirdsEye:
    camera: Camera
    size: tuple[int, int]
    x_range_m: tuple[float, float]
    y_range_m: tuple[float, float]

    @property
    def px_per_m(self) -> tuple[float, float]:
        w, h = self.size
        return w / (self.x_range_m[1] - self.x_range_m[0]), h / (self.y_range_m[1] - self.y_range_m[0])

    def bev_to_ground_a(self) -> np.ndarray:
        """3x3 affine: bird's-eye pixel (u, v, 1) -> ground metres (x, y, 1)."""
        sx, sy = self.px_per_m
        return np.array([[1 / sx, 0, self.x_range_m[0]], [0, -1 / sy, self.y_range_m[1]], [0, 0, 1]])

    @cached_property
    def _ground_to_bev_a(self) -> np.ndarray:
        # made once per view: the warps and ground_to_bev ask for it many times a frame
        return np.linalg.inv(self.bev_to_ground_a())

    @cached_property
    def _image_to_bev_h(self) -> np.ndarray:
        return self._ground_to_bev_a @ self.camera.image_to_ground_h()

    @cached_property
    def _bev_to_image_h(self) -> np.ndarray:
        return self.camera.ground_to_image_h() @ self.bev_to_ground_a()

    def image_to_bev_h(self) -> np.ndarray:
        return self._image_to_bev_h.copy()

    def bev_to_image_h(self) -> np.ndarray:
        return self._bev_to_image_h.copy()

    def visible(self) -> np.ndarray:
        """uint8 (h, w) read-only: 255 where the camera sees the ground. Fixed per view, so made
        once (every lane method and the junction detector ask for it each frame)."""
        return _visible(self)

    @cached_property
    def seen(self) -> np.ndarray:
        """bool (h, w) read-only: visible() as a mask (made once per view)."""
        mask = self.visible() > 0
        mask.setflags(write=False)
        return mask

    @cached_property
    def seen_rows(self) -> tuple[list[bool], list[int], list[int], bool]:
        """row_spans(seen), made once per view: the carriageway's scan reads it every frame."""
        return row_spans(self.seen)

    def warp(self, image: np.ndarray, interpolation: int = cv2.INTER_LINEAR) -> np.ndarray:
        """Camera image (H,W[,C], any dtype) -> bird's-eye image (size[1], size[0][,C])."""
        return cv2.warpPerspective(image, self._image_to_bev_h, self.size, flags=interpolation,
                                   borderMode=cv2.BORDER_CONSTANT)

    def unwarp(self, bev: np.ndarray, interpolation: int = cv2.INTER_LINEAR) -> np.ndarray:
        """Bird's-eye image -> camera image of the camera's size (pixels above the horizon are 0)."""
        cam = self.camera
        out = cv2.warpPerspective(bev, self._bev_to_image_h, (cam.width, cam.height),
                                  flags=interpolation, borderMode=cv2.BORDER_CONSTANT)
        out[~cam.ground_mask(1.0)] = 0
        return out

    def bev_to_ground(self, uv: np.ndarray) -> np.ndarray:
        uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
        return (np.column_stack([uv, np.ones(len(uv))]) @ self.bev_to_ground_a().T)[:, :2]

    def ground_to_bev(self, xy_m: np.ndarray) -> np.ndarray:
        xy = np.asarray(xy_m, dtype=np.float64).reshape(-1, 2)
        return (np.column_stack([xy, np.ones(len(xy))]) @ self._ground_to_bev_a.T)[:, :2]
