"""Per-track scene: road, kerb and paint polygons in world metres, barriers, textures, objects
and looks.

Everything here is computed once per track and appearance seed; the renderer then only
transforms, clips and fills what the camera can see. Ground polygons live in one array so the
rendered pixels and the label masks come from the same polygons. Two road styles
(world/track.py RoadStyle): VIA's kerbed carriageway (world/via_geometry.py) and painted lanes
(world/painted_roads.py).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import cv2
import numpy as np

from signlane.world.art import DISTRACTOR_KINDS
from signlane.world.looks import Looks, default_looks, random_looks, random_style  # noqa: F401 (re-exported)
from signlane.world.painted_roads import ASPHALT, KERB, SHADOW, WHITE, WORN, YELLOW, tile_polygons  # noqa: F401
from signlane.world.track import Track, WorldObject
from signlane.world.via_geometry import kerb_band, tile_geometry

MARKING_BIT, ROAD_BIT = 1, 2
BARRIER_HEIGHT_M = 1.0
BARRIER_LEAN_DEG = 15.0  # leaning outward, away from the road
BARRIER_STEP_M = 1.0  # barrier quads are this long


@dataclass(frozen=True)
class Paint:
    """Every ground polygon of the scene in one array: vertices (V,2) world metres, polygon k
    is verts[starts[k]:starts[k+1]]; per polygon: layer, faded flag, bounding circle."""

    verts: np.ndarray
    starts: np.ndarray
    layers: np.ndarray
    faded: np.ndarray
    centers: np.ndarray
    radii: np.ndarray

    @classmethod
    def from_polygons(cls, polys: list[tuple[int, np.ndarray, bool]]) -> "Paint":
        verts = np.concatenate([p for _, p, _ in polys]).astype(np.float64)
        starts = np.concatenate([[0], np.cumsum([len(p) for _, p, _ in polys])]).astype(np.int64)
        centers = np.array([p.mean(axis=0) for _, p, _ in polys])
        radii = np.array([np.max(np.hypot(*(p - c).T)) for (_, p, _), c in zip(polys, centers)])
        return cls(verts, starts, np.array([l for l, _, _ in polys]), np.array([f for _, _, f in polys]),
                   centers, radii)


@dataclass(frozen=True)
class Barriers:
    """Upright barrier quads: base points (Q,2,2) world metres (start, end), the outward lean of
    the top (Q,2) metres, and per-quad bounding circles for culling."""

    base: np.ndarray
    lean: np.ndarray
    centers: np.ndarray
    height_m: float = BARRIER_HEIGHT_M

    @classmethod
    def from_lines(cls, lines: list[np.ndarray], height_m: float = BARRIER_HEIGHT_M,
                   lean_deg: float = BARRIER_LEAN_DEG) -> "Barriers":
        from signlane.world.via_geometry import outward
        quads, leans = [], []
        for line in lines:
            s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(line, axis=0).T))])
            if s[-1] < 0.2:
                continue
            n = max(1, int(round(s[-1] / BARRIER_STEP_M)))
            at = np.interp(np.linspace(0, s[-1], n + 1), s, np.arange(len(line)))
            pts = np.column_stack([np.interp(at, np.arange(len(line)), line[:, k]) for k in (0, 1)])
            normals = outward(pts)
            quads.append(np.stack([pts[:-1], pts[1:]], axis=1))
            leans.append(0.5 * (normals[:-1] + normals[1:]) * height_m * math.sin(math.radians(lean_deg)))
        if not quads:
            return cls(np.zeros((0, 2, 2)), np.zeros((0, 2)), np.zeros((0, 2)), height_m)
        base = np.concatenate(quads)
        return cls(base, np.concatenate(leans), base.mean(axis=1), height_m * math.cos(math.radians(lean_deg)))


@dataclass
class Scene:
    track: Track
    looks: Looks
    paint: Paint
    objects: list[WorldObject]
    texture: np.ndarray  # (T,T) uint8 tileable noise, 128 = neutral
    texture_m: float  # metres covered by one texture tile
    panorama: np.ndarray  # (h, w, 3) uint8 background around the horizon, 360 degrees
    seed: int = 0
    barriers: Barriers | None = None
    sprite_cache: dict = field(default_factory=dict, repr=False)


def _tile_paint(track: Track, tile, looks: Looks, rng: np.random.Generator,
                barrier_lines: list) -> list[tuple[int, np.ndarray, bool]]:
    if track.style.kind == "via":
        surfaces, kerbs, lines = tile_geometry(track, tile)
        polys = [(ASPHALT, p) for p in surfaces]
        if track.style.kerb_m > 0:
            polys += [(KERB, kerb_band(e, track.style.kerb_m)) for e in kerbs]
        barrier_lines += lines
    else:
        polys = tile_polygons(track, tile)
    kept = []
    for layer, p in polys:
        if layer not in (ASPHALT, KERB) and rng.random() < looks.worn_prob:
            continue  # worn away: neither drawn nor labelled
        kept.append((layer, p, bool(layer not in (ASPHALT, KERB) and rng.random() < looks.fade_prob)))
    for _ in range(int(rng.integers(0, looks.shadows + 1)) if looks.shadows else 0):
        kept.append((SHADOW, _shadow_polygon(track, tile, rng), False))
    return kept


def _shadow_polygon(track: Track, tile, rng: np.random.Generator) -> np.ndarray:
    """A world-fixed shadow (a tree or building edge) across the tile's road."""
    cells = np.array(tile.cells, float) + np.array(track.grid_origin)
    c = track.map_to_world(cells[int(rng.integers(len(cells)))][None])[0]
    c = c + rng.uniform(-0.4, 0.4, 2) * track.cell_m
    a = rng.uniform(0, math.pi)
    length, width = rng.uniform(8, 25), rng.uniform(1.0, 6.0)
    d, n = np.array([math.cos(a), math.sin(a)]), np.array([-math.sin(a), math.cos(a)])
    k = 10
    t = np.linspace(-0.5, 0.5, k)[:, None] * length
    wob = rng.uniform(0.7, 1.3, k)[:, None] * width / 2
    return np.concatenate([c + t * d + wob * n, (c + t * d - wob * n)[::-1]])


def _noise_texture(rng: np.random.Generator, size: int = 256) -> np.ndarray:
    """Tileable multi-scale noise, uint8 around 128."""
    acc = np.zeros((size, size), np.float32)
    for cells, w in ((8, 0.5), (32, 0.3), (size, 0.2)):
        g = rng.standard_normal((cells, cells)).astype(np.float32)
        g = np.tile(g, (2, 2))
        up = cv2.resize(g, (2 * size, 2 * size), interpolation=cv2.INTER_CUBIC)
        acc += w * up[size // 2: size // 2 + size, size // 2: size // 2 + size]
    acc /= acc.std() + 1e-6
    return np.clip(128 + 40 * acc, 0, 255).astype(np.uint8)


def _panorama(rng: np.random.Generator, looks: Looks, width: int = 1440, height: int = 160) -> np.ndarray:
    """360-degree background band; the horizon is the bottom row."""
    img = np.zeros((height, width, 3), np.uint8)
    top, hor = np.array(looks.sky_top, float), np.array(looks.sky_horizon, float)
    t = np.linspace(0, 1, height)[:, None]
    img[:] = (top * (1 - t) + hor * t).astype(np.uint8)[:, None, :]
    if looks.scenery == "walls":
        # VIA's world ends in grey walls 5 m high at +-100 m: a thin band just above the horizon
        wall = _jitter_grey(rng, 150)
        img[height - int(rng.integers(3, 7)):] = wall
        return img
    _hills(img, rng, looks)
    return img


def _jitter_grey(rng: np.random.Generator, grey: int) -> tuple[int, int, int]:
    g = int(np.clip(grey + rng.normal(0, 12), 60, 230))
    return (g, g, g)


def _hills(img: np.ndarray, rng: np.random.Generator, looks: Looks) -> None:
    """Hills, trees and buildings along the horizon of a panorama (in place)."""
    height, width = img.shape[:2]
    x = np.arange(width)
    hill = np.zeros(width)
    for k in (1, 2, 3, 5, 8):
        hill += rng.uniform(0, 1) / k * np.sin(2 * math.pi * k * x / width + rng.uniform(0, 6.3))
    hill = (hill - hill.min()) / (np.ptp(hill) + 1e-9) * rng.uniform(10, 45) + 3
    col = np.array(looks.grass, float) * rng.uniform(0.5, 0.9)
    for xi in range(width):
        img[height - int(hill[xi]):, xi] = col
    for _ in range(int(rng.integers(5, 30))):
        x0 = int(rng.integers(width))
        base = height - int(hill[x0] * rng.uniform(0.2, 0.9))  # stands on the hills
        color = tuple(int(v) for v in rng.integers(40, 200, 3))
        if rng.random() < 0.4:  # a building
            w, h = int(rng.integers(10, 40)), int(rng.integers(10, 60))
            cv2.rectangle(img, (x0, base - h), (x0 + w, height), color, -1)
        else:  # a tree: trunk and crown
            h = int(rng.integers(12, 45))
            r = max(3, int(h * rng.uniform(0.25, 0.4)))
            cv2.rectangle(img, (x0 - 1, base - h // 2), (x0 + 1, height), (40, 60, 80), -1)
            green = (int(rng.integers(20, 80)), int(rng.integers(70, 150)), int(rng.integers(20, 90)))
            cv2.ellipse(img, (x0, base - h + r), (r, int(r * 1.3)), 0, 0, 360, green, -1, cv2.LINE_AA)


def build_scene(track: Track, seed: int = 0, looks: Looks | None = None,
                randomise: bool = False, looks_strength: float = 1.0) -> Scene:
    """Precompute everything the renderer needs for a track; the same seed gives the same scene."""
    rng = np.random.default_rng(seed)
    looks = looks or (random_looks(rng, looks_strength, track.style) if randomise
                      else default_looks(track.style, track.background))
    lines: list[np.ndarray] = []
    paint = Paint.from_polygons([p for t in track.tiles for p in _tile_paint(track, t, looks, rng, lines)])
    objects = list(track.signs) + list(track.distractors) + _roadside_distractors(track, rng, looks.distractors)
    texture = _noise_texture(rng)
    texture_m = looks.texture_m or float(rng.uniform(4, 10))
    barriers = Barriers.from_lines(_off_other_roads(track, paint, lines)) if lines else None
    return Scene(track, looks, paint, objects, texture, texture_m, _panorama(rng, looks), seed, barriers)


def _off_other_roads(track: Track, paint: Paint, lines: list[np.ndarray], px_per_m: float = 4.0) -> list[np.ndarray]:
    """Barrier lines split where they would stand on road (a neighbouring tile's carriageway):
    VIA's prefabs would overlap there; a car could not drive through them."""
    x0, y0, x1, y1 = track.bounds_m(margin=10.0)
    w, h = int((x1 - x0) * px_per_m) + 1, int((y1 - y0) * px_per_m) + 1
    road = np.zeros((h, w), np.uint8)
    for k in np.nonzero(paint.layers == ASPHALT)[0]:
        poly = paint.verts[paint.starts[k]:paint.starts[k + 1]]
        pix = np.column_stack([(poly[:, 0] - x0) * px_per_m, (y1 - poly[:, 1]) * px_per_m])
        cv2.fillPoly(road, [np.round(pix * 16).astype(np.int32)], 1, cv2.LINE_8, 4)
    out = []
    for line in lines:
        pix = np.column_stack([(line[:, 0] - x0) * px_per_m, (y1 - line[:, 1]) * px_per_m]).astype(int)
        pix = np.clip(pix, 0, [w - 1, h - 1])
        free = road[pix[:, 1], pix[:, 0]] == 0
        # runs of free points
        edges = np.flatnonzero(np.diff(np.concatenate([[0], free.astype(int), [0]])))
        for a, b in zip(edges[::2], edges[1::2]):
            if b - a >= 2:
                out.append(line[a:b])
    return out


def _roadside_distractors(track: Track, rng: np.random.Generator, density: float) -> list[WorldObject]:
    """Red/blue non-sign objects, cones, boxes and billboards beside plain road tiles."""
    out = []
    hw = track.style.road_half_width
    for tile in track.tiles:
        if tile.junction:
            continue
        # density is per 12 m of road, whatever the cell size
        for _ in range(int(rng.poisson(density * len(tile.cells) * track.cell_m / 12.0))):
            pts = track.centreline(tile, tile.ports[0], tile.ports[1])
            i = int(rng.integers(len(pts)))
            j = min(i + 1, len(pts) - 1) if i + 1 < len(pts) else i - 1
            d = pts[j] - pts[i]
            d = d / (np.hypot(*d) + 1e-9) * (1 if j > i else -1)
            side = 1 if rng.random() < 0.5 else -1
            n = np.array([d[1], -d[0]]) * side
            kind = DISTRACTOR_KINDS[int(rng.integers(len(DISTRACTOR_KINDS)))]
            ground = kind in ("cone", "box")
            dist = hw + (rng.uniform(0.3, 1.5) if ground else rng.uniform(1.0, 4.0))
            p = pts[i] + n * dist
            size = {"cone": 0.5, "box": 0.8, "billboard": 2.5}.get(kind, 0.75)
            height = size / 2 if ground else {"billboard": 2.5}.get(kind, 1.8)
            facing = math.atan2(-n[1], -n[0]) + rng.uniform(-0.6, 0.6)
            out.append(WorldObject(kind, float(p[0]), float(p[1]), float(facing), size, height,
                                   int(rng.integers(1 << 30))))
    return out
