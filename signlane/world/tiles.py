"""Road tiles on a VIA-style grid: their cells, the sides their road leaves by, and centrelines.

Grid frame ("map" frame): u = column axis (east), v = row axis (down the map, south); cell
units; a cell's centre sits at (col - cols/2, row - rows/2). A tile's `rot` turns it clockwise
as the map is drawn (N -> E -> S -> W). Tile geometry is defined at rot 0 about the pivot cell
centre and then rotated; see ../shared/VIA.md for the tile list.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

# sides as unit steps in (u, v)
SIDES = {"N": (0, -1), "E": (1, 0), "S": (0, 1), "W": (-1, 0)}
SIDE_OF_STEP = {v: k for k, v in SIDES.items()}
OPPOSITE = {"N": "S", "S": "N", "E": "W", "W": "E"}

TILE_NAMES = {0: "straight", 1: "cross", 2: "turn2", 3: "turn4", 4: "tee", 5: "shift"}
JUNCTION_TILES = {1, 4}
TURN_SIZE = {2: 2, 3: 4}
SHIFT_AMPLITUDE = 0.05  # lateral bulge of the lane-shift chicane, in cells
SAMPLE_STEP = 0.02  # centreline sample spacing, in cells


def rotate_step(step: tuple[int, int], rot: int) -> tuple[int, int]:
    """Rotate an integer (u, v) vector clockwise (v down) by rot degrees (multiple of 90)."""
    u, v = step
    for _ in range((rot // 90) % 4):
        u, v = -v, u
    return u, v


def rotate_points(pts: np.ndarray, rot: int) -> np.ndarray:
    a = math.radians(rot)
    c, s = math.cos(a), math.sin(a)
    return pts @ np.array([[c, s], [-s, c]])  # row-vector form of [[c,-s],[s,c]]


def rotate_side(side: str, rot: int) -> str:
    return SIDE_OF_STEP[rotate_step(SIDES[side], rot)]


@dataclass(frozen=True)
class Port:
    """Where a tile's road crosses the tile boundary: the cell it leaves from and the side."""

    cell: tuple[int, int]  # (col, row)
    side: str

    @property
    def neighbour(self) -> tuple[int, int]:
        du, dv = SIDES[self.side]
        return self.cell[0] + du, self.cell[1] + dv


@dataclass(frozen=True)
class Tile:
    index: int  # position in the map's cell_datas
    tile_id: int
    col: int
    row: int
    rot: int
    cells: tuple[tuple[int, int], ...]
    ports: tuple[Port, ...]

    @property
    def name(self) -> str:
        return TILE_NAMES[self.tile_id]

    @property
    def junction(self) -> bool:
        return self.tile_id in JUNCTION_TILES


def _local_layout(tile_id: int) -> tuple[list[tuple[int, int]], list[tuple[tuple[int, int], str]]]:
    """Cells (offsets from the pivot) and ports (cell offset, side) at rot 0."""
    if tile_id in (0, 5):
        return [(0, 0)], [((0, 0), "N"), ((0, 0), "S")]
    if tile_id == 1:
        return [(0, 0)], [((0, 0), s) for s in "NESW"]
    if tile_id == 4:
        return [(0, 0)], [((0, 0), "N"), ((0, 0), "E"), ((0, 0), "S")]
    if tile_id in TURN_SIZE:
        k = TURN_SIZE[tile_id]
        lo = -(k // 2)
        cells = [(du, dv) for dv in range(lo, lo + k) for dv in [dv] for du in range(lo, lo + k)]
        return cells, [((lo + k - 1, lo), "E"), ((lo, lo + k - 1), "S")]
    raise ValueError(f"unknown tile_id {tile_id} (known: {sorted(TILE_NAMES)})")


def make_tile(index: int, tile_id: int, col: int, row: int, rot: int) -> Tile:
    if rot % 90 != 0:
        raise ValueError(f"rot {rot} is not a multiple of 90")
    rot = int(rot) % 360
    cells, ports = _local_layout(tile_id)
    abs_cells = []
    for off in cells:
        du, dv = rotate_step(off, rot)
        abs_cells.append((col + du, row + dv))
    abs_ports = []
    for off, side in ports:
        du, dv = rotate_step(off, rot)
        abs_ports.append(Port((col + du, row + dv), rotate_side(side, rot)))
    return Tile(index, tile_id, col, row, rot, tuple(abs_cells), tuple(abs_ports))


def port_point(port: Port, grid_origin: tuple[float, float]) -> np.ndarray:
    """Map-frame (u, v) of the middle of the port's cell edge."""
    du, dv = SIDES[port.side]
    return np.array([port.cell[0] + grid_origin[0] + 0.5 * du, port.cell[1] + grid_origin[1] + 0.5 * dv])


def _arc(center: np.ndarray, radius: float, a0: float, a1: float) -> np.ndarray:
    n = max(8, int(abs(a1 - a0) * radius / SAMPLE_STEP))
    a = np.linspace(a0, a1, n)
    return center + radius * np.column_stack([np.cos(a), np.sin(a)])


def centreline_local(tile_id: int, a: str, b: str) -> np.ndarray:
    """Rot-0 centreline from side a to side b, in map-frame cells relative to the pivot centre."""
    if tile_id in TURN_SIZE:
        k = TURN_SIZE[tile_id]
        c = np.array([k / 2 - 0.5, k / 2 - 0.5])
        r = k - 0.5
        # angle measured in the (u, v) plane: E port is straight 'up' (-v) from the centre
        pts = _arc(c, r, -math.pi / 2, -math.pi)  # from E port to S port
        return pts if (a, b) == ("E", "S") else pts[::-1]
    if tile_id == 5:
        t = np.linspace(0.0, 1.0, int(1 / SAMPLE_STEP) + 1)
        pts = np.column_stack([SHIFT_AMPLITUDE * np.sin(math.pi * t) ** 2, 0.5 - t])  # S -> N
        return pts if (a, b) == ("S", "N") else pts[::-1]
    # straight and junction paths: straight line or a quarter arc between two sides
    pa = 0.5 * np.array(SIDES[a], float)
    pb = 0.5 * np.array(SIDES[b], float)
    if a == OPPOSITE[b]:
        n = int(1 / SAMPLE_STEP) + 1
        return pa + np.linspace(0, 1, n)[:, None] * (pb - pa)
    corner = pa + pb  # the cell corner between the two sides
    r = 0.5
    a0 = math.atan2(pa[1] - corner[1], pa[0] - corner[0])
    a1 = math.atan2(pb[1] - corner[1], pb[0] - corner[0])
    if a1 - a0 > math.pi:
        a1 -= 2 * math.pi
    if a0 - a1 > math.pi:
        a1 += 2 * math.pi
    return _arc(corner, r, a0, a1)


def tile_centreline(tile: Tile, a: Port, b: Port, grid_origin: tuple[float, float]) -> np.ndarray:
    """Centreline from port a to port b of a tile, map-frame cells (u, v), densely sampled."""
    inv = (360 - tile.rot) % 360
    la, lb = rotate_side(a.side, inv), rotate_side(b.side, inv)
    local = centreline_local(tile.tile_id, la, lb)
    pivot = np.array([tile.col + grid_origin[0], tile.row + grid_origin[1]])
    return rotate_points(local, tile.rot) + pivot
