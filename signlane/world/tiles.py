"""Road tiles on VIA's grid, with VIA's own conventions (../shared/VIA.md, section 4).

Grid frame: u east (columns), v north (rows; row 0 is the south row), in cells. The centre of
cell (col, row) of a W x H map sits at (col - W/2, row - H/2); world metres are grid units times
the cell size (VIA: 4 m), so x is east and y is north in both.

A tile is listed in one cell, its pivot; its layout is given at rot 0 as offsets from the pivot
and `rot` (0/90/180/270) turns it counter-clockwise seen from above: (du, dv) -> (-dv, du) per
90 degrees, and open sides turn N -> W -> S -> E. A multi-cell tile covers cells that the map
file does not mark. Paths through a tile (the road's centre line from one open end to another)
are built here in the tile's own frame, in cells, and then turned and placed.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from signlane.angles import wrap_pi

SIDES = {"N": (0, 1), "E": (1, 0), "S": (0, -1), "W": (-1, 0)}
SIDE_OF_STEP = {v: k for k, v in SIDES.items()}
OPPOSITE = {"N": "S", "S": "N", "E": "W", "W": "E"}

TILE_NAMES = {0: "straight", 1: "cross", 2: "turn2", 3: "turn4", 4: "tee", 5: "shift"}
JUNCTION_TILES = {1, 4}
SAMPLE_STEP = 0.02  # path sample spacing, in cells
TURN_SEGMENTS = 4  # VIA draws its quarter turns as chamfered polylines of 4 segments (read off its minimaps)
# quarter turns at rot 0: the centre of the arc (cells, from the pivot) and the centre-line radius
TURNS = {2: ((-1.5, -1.5), 1.5), 3: ((-2.5, -2.5), 3.5)}
SHIFT_RADIUS = 1.25  # the lane shift moves one cell sideways over two cells: two arcs of 1.25 cells (5 m)


@dataclass(frozen=True)
class Layout:
    """A tile type at rot 0: road cells, the full block it occupies, open ends (cell, side)."""

    road: tuple[tuple[int, int], ...]
    footprint: tuple[tuple[int, int], ...]
    ports: tuple[tuple[tuple[int, int], str], ...]


def _block(c0: int, c1: int, r0: int, r1: int) -> tuple[tuple[int, int], ...]:
    return tuple((c, r) for r in range(r0, r1 + 1) for c in range(c0, c1 + 1))


def _turn_road_cells(tile_id: int, block: tuple) -> tuple[tuple[int, int], ...]:
    """Cells of the block that the turn's road band (centre radius +- half a cell) touches."""
    (cx, cy), r = TURNS[tile_id]
    out = []
    for c in block:
        # nearest and farthest distance from the arc centre to the cell square
        dx = max(abs(c[0] - cx) - 0.5, 0.0)
        dy = max(abs(c[1] - cy) - 0.5, 0.0)
        far = math.hypot(abs(c[0] - cx) + 0.5, abs(c[1] - cy) + 0.5)
        if math.hypot(dx, dy) < r + 0.5 and far > r - 0.5:
            out.append(c)
    return tuple(out)


LAYOUTS: dict[int, Layout] = {
    0: Layout(((0, 0),), ((0, 0),), (((0, 0), "N"), ((0, 0), "S"))),
    1: Layout(((0, 0),), ((0, 0),), tuple(((0, 0), s) for s in "NESW")),
    2: Layout(_turn_road_cells(2, _block(-1, 0, -1, 0)), _block(-1, 0, -1, 0), (((0, -1), "S"), ((-1, 0), "W"))),
    3: Layout(_turn_road_cells(3, _block(-2, 1, -2, 1)), _block(-2, 1, -2, 1), (((1, -2), "S"), ((-2, 1), "W"))),
    4: Layout(((0, -1), (0, 0), (0, 1), (1, 0)), _block(0, 1, -1, 1), (((0, 1), "N"), ((0, -1), "S"), ((1, 0), "E"))),
    5: Layout(_block(0, 1, -1, 0), _block(0, 1, -1, 0), (((0, -1), "S"), ((1, 0), "N"))),
}


def rotate_step(step: tuple[int, int], rot: int) -> tuple[int, int]:
    """Turn an integer (u, v) offset counter-clockwise by rot degrees (a multiple of 90)."""
    u, v = step
    for _ in range((rot // 90) % 4):
        u, v = -v, u
    return u, v


def rotate_points(pts: np.ndarray, rot: float) -> np.ndarray:
    """(N, 2) points turned counter-clockwise by rot degrees about the origin."""
    a = math.radians(rot)
    c, s = math.cos(a), math.sin(a)
    return np.asarray(pts, float) @ np.array([[c, s], [-s, c]])  # row-vector form of [[c,-s],[s,c]]


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
    tile_id: int  # the type drawn (an unknown id is drawn as a straight, as VIA does)
    col: int
    row: int
    rot: int
    cells: tuple[tuple[int, int], ...]  # cells with road
    ports: tuple[Port, ...]
    footprint: tuple[tuple[int, int], ...] = ()  # the whole block, road or not
    listed_id: int | None = None  # the tile_id the file gave, when it was not a known one

    @property
    def name(self) -> str:
        return TILE_NAMES[self.tile_id]

    @property
    def junction(self) -> bool:
        return self.tile_id in JUNCTION_TILES

    def local_side(self, port: Port) -> str:
        """The side a port has in the tile's rot-0 frame."""
        return rotate_side(port.side, (360 - self.rot) % 360)


def make_tile(index: int, tile_id: int, col: int, row: int, rot: int, listed_id: int | None = None) -> Tile:
    """Place a tile type; rot must be a multiple of 90."""
    if rot % 90 != 0:
        raise ValueError(f"rot {rot} is not a multiple of 90")
    rot = int(rot) % 360
    lay = LAYOUTS[tile_id]

    def place(off):
        du, dv = rotate_step(off, rot)
        return col + du, row + dv
    ports = tuple(Port(place(off), rotate_side(side, rot)) for off, side in lay.ports)
    return Tile(index, tile_id, col, row, rot, tuple(place(c) for c in lay.road), ports,
                tuple(place(c) for c in lay.footprint), listed_id)


# --- paths in a tile's own frame (cells, rot 0, pivot cell centre at the origin) -----------------
def port_point_local(cell: tuple[int, int], side: str) -> np.ndarray:
    du, dv = SIDES[side]
    return np.array([cell[0] + 0.5 * du, cell[1] + 0.5 * dv], float)


def arc(center, radius: float, a0: float, a1: float, chamfer: int = 0) -> np.ndarray:
    """Points on an arc from angle a0 to a1 (radians); chamfer > 0 draws it as that many chords."""
    if chamfer:
        corners = np.asarray(center) + radius * np.column_stack(
            [np.cos(np.linspace(a0, a1, chamfer + 1)), np.sin(np.linspace(a0, a1, chamfer + 1))])
        return densify(corners)
    n = max(8, int(abs(a1 - a0) * radius / SAMPLE_STEP))
    a = np.linspace(a0, a1, n)
    return np.asarray(center) + radius * np.column_stack([np.cos(a), np.sin(a)])


def densify(corners: np.ndarray, step: float = SAMPLE_STEP) -> np.ndarray:
    """A polyline resampled so no two consecutive points are more than `step` apart."""
    out = [corners[:1]]
    for a, b in zip(corners[:-1], corners[1:]):
        n = max(1, int(math.ceil(float(np.hypot(*(b - a))) / step)))
        out.append(a + np.linspace(0, 1, n + 1)[1:, None] * (b - a))
    return np.concatenate(out)


def _line(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return densify(np.array([a, b], float))


def turn_path(tile_id: int, chamfer: bool) -> np.ndarray:
    """A quarter turn's centre line at rot 0, from its south end to its west end."""
    (cx, cy), r = TURNS[tile_id]
    return arc((cx, cy), r, 0.0, math.pi / 2, TURN_SEGMENTS if chamfer else 0)


def shift_path() -> np.ndarray:
    """The lane shift's centre line at rot 0: north from (0, -1.5), one cell east, to (1, 0.5)."""
    r = SHIFT_RADIUS
    theta = 2 * math.atan(0.5)  # one cell across over two cells along
    first = arc((r, -1.5), r, math.pi, math.pi - theta)
    second = arc((1 - r, 0.5), r, -theta, 0.0)
    return join([first, second])


def junction_path(tile_id: int, a: tuple[tuple[int, int], str], b: tuple[tuple[int, int], str],
                  turn_r: float) -> np.ndarray:
    """Centre line through a crossing or T-junction between two open ends at rot 0. Turns are
    quarter arcs of radius turn_r (cells) about the corner between the two arms, joined to the
    ends by straight lines; a crossing's arms are half a cell long, so its turns are at most that."""
    pa, pb = port_point_local(*a), port_point_local(*b)
    if a[1] == OPPOSITE[b[1]]:
        return _line(pa, pb)
    da = -np.array(SIDES[a[1]], float)  # travel direction on entering through a
    db = np.array(SIDES[b[1]], float)  # travel direction on leaving through b
    corner = pa * np.abs(db) + pb * np.abs(da)  # where the two arms' centre lines cross
    r = min(turn_r, float(np.hypot(*(pa - corner))), float(np.hypot(*(pb - corner))))
    start = corner - da * r
    end = corner + db * r
    centre = start + db * r
    a0 = math.atan2(*(start - centre)[::-1])
    a1 = math.atan2(*(end - centre)[::-1])
    d = wrap_pi(a1 - a0)  # the quarter turn, either way round
    return join([_line(pa, start), arc(centre, r, a0, a0 + d), _line(end, pb)])


def join(pieces: list[np.ndarray], eps: float = 1e-9) -> np.ndarray:
    """Polylines end to start, without repeated points (a path never has a zero-length step)."""
    pts = np.concatenate(pieces)
    keep = np.concatenate([[True], np.hypot(*np.diff(pts, axis=0).T) > eps])
    return pts[keep]


def local_path(tile_id: int, a: tuple[tuple[int, int], str], b: tuple[tuple[int, int], str],
               turn_r: float = 0.5, chamfer: bool = True) -> np.ndarray:
    """Centre line at rot 0 (cells from the pivot) from open end a to open end b."""
    if tile_id in TURNS:
        pts = turn_path(tile_id, chamfer)
        return pts if a[1] == "S" else pts[::-1]
    if tile_id == 5:
        pts = shift_path()
        return pts if a[1] == "S" else pts[::-1]
    if tile_id in JUNCTION_TILES:
        return junction_path(tile_id, a, b, turn_r)
    pts = _line(np.array([0.0, -0.5]), np.array([0.0, 0.5]))
    return pts if a[1] == "S" else pts[::-1]


def tile_centreline(tile: Tile, a: Port, b: Port, grid_origin: tuple[float, float],
                    turn_r: float = 0.5, chamfer: bool = True) -> np.ndarray:
    """Centre line from port a to port b of a tile, grid cells (u east, v north), densely sampled."""
    lay = LAYOUTS[tile.tile_id]
    inv = (360 - tile.rot) % 360

    def local(p: Port):
        off = rotate_step((p.cell[0] - tile.col, p.cell[1] - tile.row), inv)
        side = rotate_side(p.side, inv)
        assert (off, side) in lay.ports, (off, side)
        return off, side
    pts = local_path(tile.tile_id, local(a), local(b), turn_r, chamfer)
    pivot = np.array([tile.col + grid_origin[0], tile.row + grid_origin[1]])
    return rotate_points(pts, tile.rot) + pivot
