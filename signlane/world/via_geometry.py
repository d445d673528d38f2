"""VIA's road as its tile prefabs build it (../shared/VIA.md, sections 4 and 6): one carriageway
between white kerbs, green barriers beyond the kerbs along straights and curves, a T-junction
with filleted corners and a crossing without kerbs.

Every function works in a tile's own frame at rot 0 (metres, pivot at the origin, x east, y
north) and `place` turns and moves the result onto the map. Edges are polylines traversed with
the road on their left, so "outward" is always the right-hand normal.
"""
from __future__ import annotations

import math

import numpy as np

from signlane.world.tiles import TURN_SEGMENTS, TURNS, Tile, arc, densify, join, rotate_points, shift_path
from signlane.world.track import RoadStyle, Track


def outward(pts: np.ndarray) -> np.ndarray:
    """Unit right-hand normals of a polyline (outward for an edge with the road on its left)."""
    d = np.gradient(pts, axis=0)
    d /= np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-12)[:, None]
    return np.column_stack([d[:, 1], -d[:, 0]])


def offset(pts: np.ndarray, dist: float) -> np.ndarray:
    return pts + dist * outward(pts)


def _segment(a, b) -> np.ndarray:
    return densify(np.array([a, b], float), 0.25)


def _band_edges(centre: np.ndarray, hw: float) -> list[np.ndarray]:
    """The two edges of a band along a centre line, each with the road on its left."""
    return [offset(centre, hw), offset(centre, -hw)[::-1]]


def _polygon(edges: list[np.ndarray]) -> np.ndarray:
    return np.concatenate(edges)


def local_geometry(tile_id: int, cell_m: float, style: RoadStyle) -> tuple[list, list, list]:
    """(surface polygons, kerb edges, barrier edges) of a tile type at rot 0, in metres."""
    hw, c = style.road_half_width, cell_m
    if tile_id in TURNS:
        (cx, cy), r = TURNS[tile_id]
        centre, r = (cx * c, cy * c), r * c
        k = TURN_SEGMENTS if style.chamfer else 0
        outer = arc(centre, r + hw, 0.0, math.pi / 2, k)  # south end to west end: road on the left
        inner = arc(centre, r - hw, math.pi / 2, 0.0, k)
        edges = [outer, inner]
        return [_polygon(edges)], edges, edges
    if tile_id == 5:
        centre = shift_path() * c
        edges = _band_edges(centre, hw)
        return [_polygon(edges)], edges, edges
    if tile_id == 1:  # crossing: two bands across the cell, no kerbs, no barriers
        h = c / 2
        return ([np.array([[-hw, -h], [hw, -h], [hw, h], [-hw, h]]),
                 np.array([[-h, -hw], [h, -hw], [h, hw], [-h, hw]])], [], [])
    if tile_id == 4:
        return _tee(c, hw, min(style.fillet_m, c / 2 - hw) if c / 2 > hw else 0.0)
    centre = _segment((0.0, -c / 2), (0.0, c / 2))
    edges = _band_edges(centre, hw)
    return [_polygon(edges)], edges, edges


def _tee(c: float, hw: float, f: float) -> tuple[list, list, list]:
    """Through road x in [-hw, hw], y in [-1.5c, 1.5c]; branch to the east, y in [-hw, hw], out
    to x = 1.5c; fillets of radius f at the branch corners; a straight kerb along the west side."""
    top, end = 1.5 * c, 1.5 * c
    south = join([_segment((hw, -top), (hw, -hw - f)),
                  arc((hw + f, -hw - f), f, math.pi, math.pi / 2) if f > 0 else np.zeros((0, 2)),
                  _segment((hw + f, -hw), (end, -hw))])
    north = join([_segment((end, hw), (hw + f, hw)),
                  arc((hw + f, hw + f), f, -math.pi / 2, -math.pi) if f > 0 else np.zeros((0, 2)),
                  _segment((hw, hw + f), (hw, top))])
    west = _segment((-hw, top), (-hw, -top))
    surface = np.concatenate([south, north, west])
    return [surface], [south, north, west], []


def place(track: Track, tile: Tile, pts: np.ndarray) -> np.ndarray:
    pivot = track.cell_centre((tile.col, tile.row))
    return rotate_points(pts, tile.rot) + pivot


def kerb_band(edge: np.ndarray, width: float) -> np.ndarray:
    """The kerb's top as a ground polygon just outside an edge."""
    return np.concatenate([edge, offset(edge, width)[::-1]])


def tile_geometry(track: Track, tile: Tile) -> tuple[list[np.ndarray], list[np.ndarray], list[np.ndarray]]:
    """World-metre (surfaces, kerb edges, barrier base lines) of one tile in VIA's style."""
    style = track.style
    surf, kerbs, barriers = local_geometry(tile.tile_id, track.cell_m, style)
    surf = [place(track, tile, p) for p in surf]
    kerbs = [place(track, tile, e) for e in kerbs]
    lines = []
    if style.barrier_gap_m >= 0:
        lines = [offset(place(track, tile, e), style.kerb_m + style.barrier_gap_m) for e in barriers]
    return surf, kerbs, lines
