"""Painted roads: asphalt bands along centre lines with edge and centre lines, and junction boxes.

Every function returns (layer, polygon) pairs in world metres; the renderer fills them and the
label masks come from the same polygons.
"""
from __future__ import annotations

import numpy as np

from signlane.world.tiles import SIDES
from signlane.world.track import RoadStyle, Track

# paint layers, drawn in this order; see world/scene.py
ASPHALT, WHITE, YELLOW, WORN, SHADOW, KERB = 0, 1, 2, 3, 4, 5
PAINT = {"white": WHITE, "yellow": YELLOW}


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
    c = track.cell_centre((tile.col, tile.row))
    cm = track.cell_m
    polys: list[tuple[int, np.ndarray]] = [(ASPHALT, c + np.array([[-hw, -hw], [hw, -hw], [hw, hw], [-hw, hw]]))]
    open_sides = {p.side for p in tile.ports}
    edge = style.lanes * style.lane_width / 2
    for side, (du, dv) in SIDES.items():
        out = np.array([du, dv], float)  # world direction of that side
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




def tile_polygons(track: Track, tile) -> list[tuple[int, np.ndarray]]:
    """A tile's painted road. A T-junction is a junction box in its pivot cell and plain road
    along its three arms (VIA's T is a 2x3 block: the through road spans three cells)."""
    if not tile.junction:
        return road_polygons(track.centreline(tile, tile.ports[0], tile.ports[1]), track.style)
    polys = junction_polygons(track, tile)
    c = track.cell_centre((tile.col, tile.row))
    for port in tile.ports:
        if port.cell == (tile.col, tile.row):
            continue
        out = np.array(SIDES[port.side], float)
        a = c + out * 0.5 * track.cell_m
        b = track.cell_centre(port.cell) + out * 0.5 * track.cell_m
        n = max(2, int(np.hypot(*(b - a)) / 0.25))
        polys += road_polygons((a + np.linspace(0, 1, n)[:, None] * (b - a))[::-1], track.style)
    return polys
