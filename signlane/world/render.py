"""Camera view of a scene with exact ground truth.

The road is drawn as ground-plane polygons (asphalt, paint, shadows) clipped to the camera's
near plane and projected with the ground->image homography; the label image is filled from the
same polygons, so the marking mask and the rendered paint agree by construction. A tileable
world-fixed noise texture gives the ground its grain; a 360-degree panorama gives the horizon.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import cv2
import numpy as np

from signlane.camera import Camera
from signlane.world.effects import Effects, apply_effects
from signlane.world.barriers import draw_barriers
from signlane.world.objects import draw_objects
from signlane.world.route import Pose, Route
from signlane.world.scene import ASPHALT, KERB, SHADOW, WHITE, YELLOW, Scene
from signlane.world.truth import GroundTruth, compute_truth

NEAR_M = 0.05  # polygons are clipped to this depth in front of the camera (a camera 0.2 m up sees ground 0.1 m off)
VIEW_RANGE_M = 80.0  # beyond this, paint is a few pixels under the fogged horizon
PANO_PX_PER_DEG = 4.0
BARRIER_ID = 7  # paint id of barrier pixels (drawn upright after the ground)


@dataclass(frozen=True)
class Sample:
    image: np.ndarray  # uint8 (H, W, 3) BGR
    truth: GroundTruth
    # the same frame before the camera's photometric effects (exposure, blur, noise, glare, rain,
    # JPEG): lets a dataset ask whether a sign's symbol survived them
    clean: np.ndarray | None = None


class Renderer:
    """Renders a scene; `render` is a pure function of (pose, camera, effects, rng)."""

    def __init__(self, scene: Scene, sign_strength: float = 0.0):
        self.scene = scene
        self.sign_strength = sign_strength  # appearance randomisation of sign sprites
        self._pano = np.concatenate([scene.panorama, scene.panorama[:, :64]], axis=1)
        self._palette_lut = self._palette()  # paint id -> BGR; the scene's colours do not change
        # the texture's own contrast is about 0.3; scale it to the scene's texture strength once
        scale = scene.looks.texture / 0.3
        self._texture_img = cv2.addWeighted(scene.texture, scale, scene.texture, 0, 128 * (1 - scale))
        # how much of the texture each paint id gets (VIA's asphalt is nearly uniform)
        share = np.ones(256, np.float32)
        share[1:7] = scene.looks.road_texture
        share[BARRIER_ID] = 0.3
        self._texture_share = share

    # --- public --------------------------------------------------------------------------
    def render_on_route(self, route: Route, s: float, camera: Camera, lateral_m: float = 0.0,
                        heading_offset: float = 0.0, effects: Effects | None = None,
                        rng: np.random.Generator | None = None) -> Sample:
        pose = route.pose_at(s, lateral_m, heading_offset)
        return self.render(pose, camera, effects, rng, route=route, s_hint=s)

    def render(self, pose: Pose, camera: Camera, effects: Effects | None = None,
               rng: np.random.Generator | None = None, route: Route | None = None,
               s_hint: float | None = None) -> Sample:
        effects = effects or Effects.clean()
        rng = rng if rng is not None else np.random.default_rng(0)
        nominal = camera
        camera = effects.jitter_camera(camera, rng)
        image, label, drawn = self._draw(pose, camera)
        clean, image = image, apply_effects(image, effects, rng)
        truth = compute_truth(self.scene, pose, camera, label, drawn, route, s_hint)
        return Sample(image, replace(truth, nominal_camera=nominal), clean)

    # --- drawing -----------------------------------------------------------------------------
    def _draw(self, pose: Pose, camera: Camera):
        W, H = camera.width, camera.height
        geo = _camera_maps(camera)
        w2g = pose.world_to_ground_a()
        g2i = camera.ground_to_image_h()
        # paint ids: one fill per polygon; colours come from a palette afterwards
        ids = np.zeros((H, W), np.uint8)
        shadow = None
        for layer, pts, faded in self._visible_polygons(w2g, camera, g2i):
            if layer == SHADOW:
                if shadow is None:
                    shadow = np.full((H, W), 255, np.uint8)
                cv2.fillPoly(shadow, [pts], 120, cv2.LINE_AA, 4)
                continue
            cv2.fillPoly(ids, [pts], _PAINT_ID[layer] + (2 if faded else 0), cv2.LINE_8, 4)
        cv2.multiply(ids, geo.ground_u8, ids)
        if self.scene.barriers is not None:
            draw_barriers(ids, self.scene.barriers, w2g, camera, BARRIER_ID)
        image = cv2.LUT(cv2.merge([ids, ids, ids]), self._palette_lut)
        image = cv2.GaussianBlur(image, (3, 3), 0.6)  # stands in for anti-aliasing
        self._texture(image, ids, pose, camera, shadow, geo.ground_top)
        self._sky(image, pose, camera, geo)
        drawn = draw_objects(image, self.scene.objects, camera, w2g, self.scene.sprite_cache, self.sign_strength,
                             self.scene.looks.sign_gain, self.scene.track.style.kind == "via")
        return image, ids, drawn

    def _palette(self) -> np.ndarray:
        lk = self.scene.looks
        fade = [tuple(int(0.45 * c + 0.55 * a) for c, a in zip(col, lk.asphalt)) for col in (lk.white, lk.yellow)]
        table = np.zeros((256, 1, 3), np.uint8)
        for i, col in enumerate([lk.grass, lk.asphalt, lk.white, lk.yellow, *fade, lk.kerb, lk.barrier]):
            table[i, 0] = col
        return table

    def _visible_polygons(self, w2g: np.ndarray, camera: Camera, g2i: np.ndarray):
        """(layer, image polygon as int32 1/16-pixel points, faded) for paint near enough and in
        front of the camera, clipped to the near plane, in drawing order."""
        paint = self.scene.paint
        rot, shift = w2g[:2, :2], w2g[:2, 2]
        c = paint.centers @ rot.T + shift
        sel = np.nonzero((c[:, 1] > -paint.radii) & (np.hypot(c[:, 0], c[:, 1]) < VIEW_RANGE_M + paint.radii))[0]
        if len(sel) == 0:
            return []
        lengths = paint.starts[sel + 1] - paint.starts[sel]
        new_starts = np.concatenate([[0], np.cumsum(lengths)])
        idx = np.arange(new_starts[-1]) - np.repeat(new_starts[:-1] - paint.starts[sel], lengths)
        verts = paint.verts[idx] @ rot.T + shift
        depth = verts @ camera.R[2, :2] + camera.t[2]
        dmax = np.maximum.reduceat(depth, new_starts[:-1])
        dmin = np.minimum.reduceat(depth, new_starts[:-1])
        pix = _to_fixed(_project(verts, g2i))
        # polygons entirely in front of the camera but off-screen need no fill
        lo = np.minimum.reduceat(pix, new_starts[:-1])
        hi = np.maximum.reduceat(pix, new_starts[:-1])
        onscreen = (hi[:, 0] >= 0) & (lo[:, 0] < camera.width * 16) & (hi[:, 1] >= 0) & (lo[:, 1] < camera.height * 16)
        keep = np.nonzero((dmax > NEAR_M) & ((dmin < NEAR_M) | onscreen))[0]
        layers, faded = paint.layers[sel], paint.faded[sel]
        keep = keep[np.argsort(_ORDER_LUT[layers[keep]], kind="stable")]  # asphalt, paint, shadows
        out = []
        for k in keep:
            i0, i1 = new_starts[k], new_starts[k + 1]
            if dmin[k] < NEAR_M:
                poly = _clip_near(verts[i0:i1], depth[i0:i1])
                if len(poly) < 3:
                    continue
                out.append((layers[k], _to_fixed(_project(poly, g2i)), faded[k]))
            else:
                out.append((layers[k], pix[i0:i1], faded[k]))
        return out

    def _texture(self, image: np.ndarray, ids: np.ndarray, pose: Pose, camera: Camera,
                 shadow: np.ndarray | None, top: int) -> None:
        """Multiply the ground rows by a world-fixed noise texture (each surface its share of
        it) and by shadows."""
        if top >= camera.height:
            return
        sc = self.scene
        n = sc.texture.shape[0]
        k = n / sc.texture_m  # texture pixels per metre
        world_to_tex = np.array([[k, 0, 0], [0, -k, 0], [0, 0, 1.0]])
        # warp at half resolution (the texture is smooth) and upsample
        band = np.array([[2, 0, 0], [0, 2, top], [0, 0, 1.0]])  # half-res band pixel -> image pixel
        h = world_to_tex @ pose.ground_to_world_a() @ camera.image_to_ground_h() @ band
        rows_n = camera.height - top
        small = ((camera.width + 1) // 2, (rows_n + 1) // 2)
        t = cv2.warpPerspective(self._texture_img, h, small, flags=cv2.WARP_INVERSE_MAP | cv2.INTER_LINEAR,
                                borderMode=cv2.BORDER_WRAP)
        t = cv2.resize(t, (camera.width, rows_n), interpolation=cv2.INTER_LINEAR)
        share = self._texture_share[ids[top:]]
        t = (128.0 + (t.astype(np.float32) - 128.0) * share).astype(np.uint8)
        if shadow is not None:
            t = cv2.multiply(t, shadow[top:], scale=1 / 255.0)
        rows = image[top:]
        cv2.multiply(rows, cv2.cvtColor(t, cv2.COLOR_GRAY2BGR), rows, scale=1 / 128.0)

    def _sky(self, image: np.ndarray, pose: Pose, camera: Camera, geo: "_CameraMaps") -> None:
        """Panorama above the horizon (an affine approximation of the angular mapping), then fog."""
        f = camera.focal_px
        k = PANO_PX_PER_DEG * math.degrees(1.0 / f)
        pano = self._pano
        ph, pw = pano.shape[:2]
        full = pw - 64
        roll = math.radians(camera.roll_deg)
        cx = camera.width / 2
        hor_y = camera.height / 2 - f * math.tan(math.radians(camera.pitch_deg))
        az = (90.0 - math.degrees(pose.heading) + camera.yaw_deg) % 360.0  # compass bearing
        c, s = math.cos(roll), math.sin(roll)
        m = np.array([[k * c, k * s, 0.0], [-k * s, k * c, 0.0]])
        m[:, 2] = np.array([(az * PANO_PX_PER_DEG) % full, ph - 1]) - m[:, :2] @ np.array([cx, hor_y])
        bottom = geo.sky_bottom
        if bottom > 0:
            sky = cv2.warpAffine(pano, m, (camera.width, bottom), flags=cv2.WARP_INVERSE_MAP | cv2.INTER_LINEAR,
                                 borderMode=cv2.BORDER_REPLICATE)
            cv2.copyTo(sky, geo.sky_u8[:bottom], image[:bottom])
        fog_rows, fog_alpha = geo.fog(self.scene.looks.fog_m)
        if fog_rows[1] > fog_rows[0]:
            r0, r1 = fog_rows
            hz = np.array(self.scene.looks.sky_horizon, np.float32)
            band = image[r0:r1].astype(np.float32)
            band += fog_alpha * (hz - band)
            image[r0:r1] = band.astype(np.uint8)


@dataclass(frozen=True)
class _CameraMaps:
    """Per-camera masks and fog weights (cached: they depend on the camera alone)."""

    ground: np.ndarray  # bool (H, W)
    ground_u8: np.ndarray  # uint8 (H, W) 0/1
    sky: np.ndarray  # bool (H, W)
    sky_u8: np.ndarray  # uint8 (H, W) 0/1, for cv2.copyTo
    ground_top: int  # first row with ground pixels
    sky_bottom: int  # one past the last row with sky pixels
    dist: np.ndarray  # float32 (H, W): metres to the ground each pixel sees (inf above the horizon)
    _fog: dict = field(default_factory=dict, repr=False)

    def fog(self, fog_m: tuple[float, float]) -> tuple[tuple[int, int], np.ndarray]:
        """Rows with fog and its weight (float32 (rows, W, 1)) for a fog from fog_m[0] to fog_m[1]."""
        if fog_m not in self._fog:
            start, full = fog_m
            alpha = np.clip((self.dist - start) / max(full - start, 1e-3), 0, 0.85).astype(np.float32)
            alpha[self.sky] = 0
            rows = np.nonzero(alpha.max(axis=1) > 0.01)[0]
            r0, r1 = (int(rows[0]), int(rows[-1]) + 1) if len(rows) else (0, 0)
            self._fog[fog_m] = ((r0, r1), alpha[r0:r1, :, None].copy())
        return self._fog[fog_m]


_MAPS_CACHE: dict[Camera, _CameraMaps] = {}


def _camera_maps(camera: Camera) -> _CameraMaps:
    maps = _MAPS_CACHE.get(camera)
    if maps is not None:
        return maps
    ground = camera.ground_mask(0.0)
    sky = ~ground
    rows_g = np.nonzero(ground.any(axis=1))[0]
    rows_s = np.nonzero(sky.any(axis=1))[0]
    n, c = camera.horizon()
    u = np.arange(camera.width, dtype=np.float32) + 0.5
    v = np.arange(camera.height, dtype=np.float32) + 0.5
    val = (n[0] * u[None, :] + n[1] * v[:, None] + c) / (np.hypot(*n) + 1e-12)  # px below the horizon
    dist = (camera.height_m * camera.focal_px / np.maximum(val, 1e-3)).astype(np.float32)
    maps = _CameraMaps(ground, ground.astype(np.uint8), sky, sky.astype(np.uint8), int(rows_g[0]) if len(rows_g) else camera.height,
                       int(rows_s[-1]) + 1 if len(rows_s) else 0, dist)
    if len(_MAPS_CACHE) > 64:
        _MAPS_CACHE.clear()
    _MAPS_CACHE[camera] = maps
    return maps


_ORDER_LUT = np.zeros(8, np.int64)
_ORDER_LUT[[ASPHALT, KERB, WHITE, YELLOW, SHADOW]] = [0, 1, 2, 2, 3]
_PAINT_ID = {ASPHALT: 1, WHITE: 2, YELLOW: 3, KERB: 6}  # palette index; faded paint adds 2


def _to_fixed(pix: np.ndarray) -> np.ndarray:
    """Pixels -> int32 points with 4 fractional bits (cv2 drawing with shift=4), clamped so
    far-off vertices cannot overflow."""
    return np.round(np.clip(pix, -1e5, 1e5) * 16).astype(np.int32)


def _project(poly_ground: np.ndarray, g2i: np.ndarray) -> np.ndarray:
    h = poly_ground @ g2i[:, :2].T + g2i[:, 2]
    return h[:, :2] / h[:, 2:3]


def _clip_near(poly: np.ndarray, depth: np.ndarray) -> np.ndarray:
    """Sutherland-Hodgman clip of a polygon to depth >= NEAR_M (one plane, vectorised)."""
    nxt = np.roll(np.arange(len(poly)), -1)
    inside = depth >= NEAR_M
    cross = inside != inside[nxt]
    t = (NEAR_M - depth) / np.where(cross, depth[nxt] - depth, 1.0)
    hit = poly + t[:, None] * (poly[nxt] - poly)
    cand = np.stack([poly, hit], axis=1).reshape(-1, 2)
    keep = np.stack([inside, cross], axis=1).reshape(-1)
    return cand[keep]
