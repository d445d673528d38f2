"""Per-track scene: road and paint polygons in world metres, textures, objects and looks.

Everything here is computed once per track and appearance seed; the renderer then only
transforms, clips and fills what the camera can see. Paint is a polygon list per tile so the
rendered pixels and the label masks come from the same polygons.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import cv2
import numpy as np

from signlane.world.art import DISTRACTOR_KINDS
from signlane.world.tiles import SIDES
from signlane.world.track import RoadStyle, Track, WorldObject

# paint layers, drawn in this order; the label bit each sets in the label image
ASPHALT, WHITE, YELLOW, WORN, SHADOW = 0, 1, 2, 3, 4
MARKING_BIT, ROAD_BIT = 1, 2

PAINT = {"white": WHITE, "yellow": YELLOW}


@dataclass(frozen=True)
class Looks:
    """Scene colours (BGR) and texture strengths."""

    asphalt: tuple[int, int, int] = (92, 92, 96)
    grass: tuple[int, int, int] = (60, 120, 80)
    white: tuple[int, int, int] = (235, 235, 235)
    yellow: tuple[int, int, int] = (40, 190, 230)
    sky_top: tuple[int, int, int] = (225, 170, 110)
    sky_horizon: tuple[int, int, int] = (235, 215, 195)
    texture: float = 0.12  # multiplicative noise amplitude of the ground texture
    worn_prob: float = 0.0  # chance a paint piece is missing
    fade_prob: float = 0.0  # chance a paint piece is faded towards the asphalt
    shadows: int = 0  # number of world-fixed shadow polygons per tile-ish area


def random_looks(rng: np.random.Generator, strength: float = 1.0) -> Looks:
    def jitter(c, amount):
        return tuple(int(np.clip(v + rng.normal(0, amount * strength), 0, 255)) for v in c)
    grey = float(rng.uniform(60, 130))
    asphalt = tuple(int(np.clip(grey + rng.normal(0, 6 * strength), 0, 255)) for _ in range(3))
    grass_options = [(60, 120, 80), (70, 140, 150), (110, 150, 160), (90, 100, 90), (50, 90, 60)]
    grass = jitter(grass_options[int(rng.integers(len(grass_options)))], 15)
    return Looks(asphalt=asphalt, grass=grass, white=jitter((235, 235, 235), 12),
                 yellow=jitter((40, 190, 230), 15), sky_top=jitter((225, 170, 110), 25),
                 sky_horizon=jitter((235, 215, 195), 20), texture=float(rng.uniform(0.04, 0.2)),
                 worn_prob=float(min(0.6, rng.uniform(0, 0.25) * strength)),
                 fade_prob=float(min(0.8, rng.uniform(0, 0.3) * strength)),
                 shadows=int(round(rng.integers(0, 4) * strength)))


def random_style(rng: np.random.Generator) -> RoadStyle:
    lanes = 2 if rng.random() < 0.8 else 1
    centre = ["dashed", "dashed", "solid", "double", "none"][int(rng.integers(5))]
    centre_color = "yellow" if rng.random() < 0.35 else "white"
    return RoadStyle(lane_width=float(rng.uniform(2.8, 3.8)), lanes=lanes,
                     shoulder=float(rng.uniform(0.2, 0.9)), line_width=float(rng.uniform(0.1, 0.25)),
                     edge_line="dashed" if rng.random() < 0.1 else "solid", centre_line=centre,
                     edge_color="yellow" if rng.random() < 0.1 else "white", centre_color=centre_color,
                     dash_m=float(rng.uniform(1.5, 4.0)), gap_m=float(rng.uniform(1.5, 6.0)))


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
    sprite_cache: dict = field(default_factory=dict, repr=False)


def _band(pts: np.ndarray, normals: np.ndarray, d0: float, d1: float) -> np.ndarray:
    """Polygon of the strip between lateral offsets d0 and d1 (metres, + = right)."""
    a = pts + d0 * normals
    b = pts + d1 * normals
    return np.concatenate([a, b[::-1]])


def _frame(pts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    d = np.gradient(pts, axis=0)
    d /= np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-12)[:, None]
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(pts, axis=0).T))])
    return np.column_stack([d[:, 1], -d[:, 0]]), s


def _dashes(pts, normals, s, d0, d1, dash, gap) -> list[np.ndarray]:
    """Dash polygons along the strip; the period is fitted to the piece length."""
    length = s[-1]
    period = dash + gap
    n = max(1, int(round(length / period)))
    period = length / n
    frac = dash / (dash + gap)
    out = []
    for k in range(n):
        a, b = k * period + 0.5 * (1 - frac) * period, k * period + 0.5 * (1 + frac) * period
        i0, i1 = np.searchsorted(s, a), np.searchsorted(s, b)
        if i1 - i0 >= 1:
            out.append(_band(pts[i0:i1 + 1], normals[i0:i1 + 1], d0, d1))
    return out


def _line(pts, normals, s, offset, width, kind, style) -> list[np.ndarray]:
    h = width / 2
    if kind == "none":
        return []
    if kind == "double":
        g = style.double_gap / 2 + h
        return [_band(pts, normals, offset - g - h, offset - g + h), _band(pts, normals, offset + g - h, offset + g + h)]
    if kind == "dashed":
        return _dashes(pts, normals, s, offset - h, offset + h, style.dash_m, style.gap_m)
    return [_band(pts, normals, offset - h, offset + h)]


def road_polygons(pts: np.ndarray, style: RoadStyle, with_paint: bool = True) -> list[tuple[int, np.ndarray]]:
    """(layer, polygon) list for a road piece along centreline pts (world metres)."""
    normals, s = _frame(pts)
    hw = style.road_half_width
    polys = [(ASPHALT, _band(pts, normals, -hw, hw))]
    if not with_paint:
        return polys
    edge = style.lanes * style.lane_width / 2
    ec, cc = PAINT[style.edge_color], PAINT[style.centre_color]
    for off in (-edge, edge):
        polys += [(ec, p) for p in _line(pts, normals, s, off, style.line_width, style.edge_line, style)]
    if style.lanes == 2:
        polys += [(cc, p) for p in _line(pts, normals, s, 0.0, style.line_width, style.centre_line, style)]
    return polys


def junction_polygons(track: Track, tile) -> list[tuple[int, np.ndarray]]:
    """A square of asphalt with road stubs to each open side; edge lines on closed sides."""
    style = track.style
    hw = style.road_half_width
    half_cell = 0.5
    c = track.map_to_world(np.array([[tile.col + track.grid_origin[0], tile.row + track.grid_origin[1]]]))[0]
    cm = track.cell_m
    polys: list[tuple[int, np.ndarray]] = [(ASPHALT, c + np.array([[-hw, -hw], [hw, -hw], [hw, hw], [-hw, hw]]))]
    open_sides = {p.side for p in tile.ports}
    edge = style.lanes * style.lane_width / 2
    for side, (du, dv) in SIDES.items():
        out = np.array([du, -dv], float)  # world direction of that side
        if side in open_sides:
            a = c + out * hw
            b = c + out * half_cell * cm
            n = max(2, int(np.hypot(*(b - a)) / 0.25))
            pts = a + np.linspace(0, 1, n)[:, None] * (b - a)
            polys += road_polygons(pts[::-1], style)  # drawn travelling into the junction
        else:
            left = np.array([-out[1], out[0]])
            pts = c + out * edge + np.linspace(-hw, hw, 8)[:, None] * left
            h = style.line_width / 2
            polys.append((PAINT[style.edge_color], np.concatenate([pts - out * h, (pts + out * h)[::-1]])))
    return polys


def _tile_paint(track: Track, tile, looks: Looks, rng: np.random.Generator) -> list[tuple[int, np.ndarray, bool]]:
    if tile.junction:
        polys = junction_polygons(track, tile)
    else:
        polys = road_polygons(track.centreline(tile, tile.ports[0], tile.ports[1]), track.style)
    kept = []
    for layer, p in polys:
        if layer != ASPHALT and rng.random() < looks.worn_prob:
            continue  # worn away: neither drawn nor labelled
        kept.append((layer, p, bool(layer != ASPHALT and rng.random() < looks.fade_prob)))
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
    """360-degree background band; the horizon is the bottom row. Hills, trees and buildings."""
    img = np.zeros((height, width, 3), np.uint8)
    top, hor = np.array(looks.sky_top, float), np.array(looks.sky_horizon, float)
    t = np.linspace(0, 1, height)[:, None]
    img[:] = (top * (1 - t) + hor * t).astype(np.uint8)[:, None, :]
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
    return img


def build_scene(track: Track, seed: int = 0, looks: Looks | None = None,
                randomise: bool = False, looks_strength: float = 1.0) -> Scene:
    """Precompute everything the renderer needs for a track; the same seed gives the same scene."""
    rng = np.random.default_rng(seed)
    looks = looks or (random_looks(rng, looks_strength) if randomise else Looks())
    paint = Paint.from_polygons([p for t in track.tiles for p in _tile_paint(track, t, looks, rng)])
    objects = list(track.signs) + list(track.distractors) + _roadside_distractors(track, rng)
    return Scene(track, looks, paint, objects, _noise_texture(rng), float(rng.uniform(4, 10)),
                 _panorama(rng, looks), seed)


def _roadside_distractors(track: Track, rng: np.random.Generator, density: float = 0.08) -> list[WorldObject]:
    """Red/blue non-sign objects, cones, boxes and billboards beside plain road tiles."""
    out = []
    hw = track.style.road_half_width
    for tile in track.tiles:
        if tile.junction:
            continue
        for _ in range(int(rng.poisson(density * len(tile.cells)))):
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
