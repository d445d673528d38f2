"""Track model: a VIA map's grid of road tiles in world metres, its signs and distractors.

World frame: metres, x east (map columns), y north (map rows), headings in radians
counter-clockwise from +x. Maps follow VIA's own conventions (world/tiles.py, ../shared/VIA.md);
procedural tracks are generated as VIA map dicts (world/procedural.py), so one loader serves both.

Like VIA, the loader takes what VIA's editor writes: dead ends are reported, not refused; an
unknown tile id is drawn as a straight; overlapping tiles are reported. A file that cannot be a
map at all (not JSON, no grid, a number that is not finite) gets one clear line (MapError).
"""
from __future__ import annotations

import json
import logging
import math
from dataclasses import dataclass, field, replace
from pathlib import Path as FsPath

import numpy as np

from signlane.world.art import VIA_SIGN_IDS as VIA_SIGN_NAMES
from signlane.world.tiles import LAYOUTS, OPPOSITE, SIDES, Port, Tile, make_tile, tile_centreline

log = logging.getLogger(__name__)

VIA_CELL_M = 4.0  # VIA's cell, and its carriageway's width
JUNCTION_TURN_M = 4.5  # reference turn radius through junctions: VIA's car turns no tighter than 4.2 m
SIGN_FACE_M = 1.25  # VIA's sign face (square), centred this high above the road:
SIGN_HEIGHT_M = 2.42
MAX_MAP_CELLS = 1000  # a side longer than this is not a map anyone drew
BACKGROUNDS = {0: "grass", 1: "ground"}  # VIA's bg_id; any other value: neither (walls and sky only)


class MapError(ValueError):
    """A map file that cannot be turned into a track: str(e) is one line naming the problem."""


@dataclass(frozen=True)
class RoadStyle:
    """How roads look and how wide they are. `kind` "painted": lanes with painted lines on wider
    cells; "via": VIA's one 4 m carriageway between white kerbs, no paint, green barriers.
    Widths in metres."""

    kind: str = "painted"
    cell_m: float = 12.0
    lane_width: float = 3.2
    lanes: int = 2  # 1 (single lane) or 2 (one per direction, right-hand traffic)
    shoulder: float = 0.5  # asphalt outside each edge line
    line_width: float = 0.15
    edge_line: str = "solid"  # solid | dashed | none
    centre_line: str = "dashed"  # solid | dashed | double | none (two-lane roads only)
    edge_color: str = "white"  # white | yellow
    centre_color: str = "white"
    dash_m: float = 3.0
    gap_m: float = 4.0
    double_gap: float = 0.15  # gap between the two strokes of a double line
    kerb_m: float = 0.0  # white kerb just outside each road edge (VIA: 0.18 m wide, 0.1 m high)
    barrier_gap_m: float = -1.0  # barriers this far beyond the kerbs (VIA: 2 m); < 0: none
    fillet_m: float = 1.6  # corner fillets of a VIA T-junction's branch
    chamfer: bool = False  # quarter turns as VIA's chamfered polylines instead of arcs

    @classmethod
    def via(cls, **kw) -> "RoadStyle":
        return cls(**{**dict(kind="via", cell_m=VIA_CELL_M, lane_width=VIA_CELL_M, lanes=1, shoulder=0.0,
                             edge_line="none", centre_line="none", kerb_m=0.18, barrier_gap_m=2.0,
                             chamfer=True), **kw})

    @classmethod
    def named(cls, name: str) -> "RoadStyle":
        if name == "via":
            return cls.via()
        if name == "painted":
            return cls()
        raise ValueError(f"unknown road style {name!r} (via, painted)")

    @property
    def road_half_width(self) -> float:
        if self.kind == "via":
            return self.lane_width / 2
        return self.lanes * self.lane_width / 2 + self.shoulder

    def ego_lane_offset(self) -> float:
        """Ego-lane centre, metres right of the road centreline (right-hand traffic)."""
        return self.lane_width / 2 if self.lanes == 2 else 0.0

    @property
    def offroad_m(self) -> float:
        """Cross-track error (from the ego-lane centre) beyond which the car is off its road: on a
        kerbed carriageway its centre is over the kerb; on a painted road, 0.5 m past its lane."""
        return self.road_half_width if self.kind == "via" else self.lane_width / 2 + 0.5

    @property
    def turn_r_cells(self) -> float:
        return max(0.5, JUNCTION_TURN_M / self.cell_m)


@dataclass(frozen=True)
class WorldObject:
    """A sign or distractor standing in the world. facing = direction its face points (rad)."""

    kind: str  # sign class name, or a distractor kind from world.art
    x: float
    y: float
    facing: float
    size_m: float = SIGN_FACE_M  # face height (and width, for square faces)
    height_m: float = SIGN_HEIGHT_M  # height of the face centre above the ground
    seed: int = 0  # appearance seed


@dataclass
class Track:
    name: str
    cols: int
    rows: int
    cell_m: float
    tiles: list[Tile]
    signs: list[WorldObject] = field(default_factory=list)
    distractors: list[WorldObject] = field(default_factory=list)
    style: RoadStyle = field(default_factory=RoadStyle)
    start_cell: tuple[int, int] = (0, 0)
    background: str = "grass"  # grass | ground | none (VIA's bg_id)
    warnings: list[str] = field(default_factory=list)
    dead_ends: list[tuple[Tile, Port]] = field(default_factory=list)
    _cell_tile: dict[tuple[int, int], Tile] = field(default_factory=dict, repr=False)
    _centrelines: dict[tuple[int, Port, Port], np.ndarray] = field(default_factory=dict, repr=False)
    _viable: set = field(default_factory=set, repr=False)

    # --- construction ----------------------------------------------------------------
    @classmethod
    def from_via(cls, data: dict, style: RoadStyle | None = None, cell_m: float | None = None,
                 source: str = "map") -> "Track":
        """Build a track from a VIA map dict (default style: VIA's own). Raises MapError for a
        file that cannot be a map; what VIA would still draw is kept and reported in `warnings`."""
        style = style or RoadStyle.via()
        if cell_m is not None:
            style = replace(style, cell_m=float(cell_m))
        cols, rows, cells = _grid(data, source)
        warnings: list[str] = []
        tiles: list[Tile] = []
        owner: dict[tuple[int, int], Tile] = {}
        for i, cd in enumerate(cells):
            tile = _tile(i, cd, cols, rows, source, warnings)
            for c in tile.cells:
                if c in owner:
                    warnings.append(f"{_where(tile)} overlaps {_where(owner[c])} at cell (col {c[0]}, row {c[1]})")
                    continue
                owner[c] = tile
            tiles.append(tile)
        if not tiles:
            raise MapError(f"{source}: the map has no road cells")
        bg = _number(data.get("bg_id", 0), "bg_id", source)
        track = cls(str(data.get("map_name", source)), cols, rows, style.cell_m, tiles, style=style,
                    background=BACKGROUNDS.get(int(bg), "none"), warnings=warnings, _cell_tile=owner)
        track._link()
        track.start_cell = track._start_cell(data.get("car_pos"), source)
        track.signs = [s for i, raw in enumerate(data.get("sign_obj_datas") or [])
                       if (s := _sign_from_via(track, raw, i, source)) is not None]
        track.distractors = [WorldObject(**d) for d in data.get("signlane_distractors", [])]
        return track

    @classmethod
    def load(cls, path: str | FsPath, **kw) -> "Track":
        """A map file; what VIA would draw oddly is logged as warnings (see `warnings`)."""
        track = cls.from_via(read_map(path), source=str(path), **kw)
        for w in track.warnings:
            log.warning("%s: %s", path, w)
        return track

    def _link(self) -> None:
        """Find the dead ends (an open end with no road entering it) and which ways out of each
        tile can be driven on for ever (not into a dead-end branch)."""
        for tile in sorted(self.tiles, key=lambda t: (t.row, t.col)):
            if all(self._cell_tile.get(c) is not tile for c in tile.cells):
                continue  # wholly under another tile (reported as an overlap)
            for port in tile.ports:
                if self.next_tile(tile, port) is None:
                    self.dead_ends.append((tile, port))
                    other = self._cell_tile.get(port.neighbour)
                    what = "nothing" if other is None else f"the side of a {other.name} tile"
                    self.warnings.append(f"dead end: {_where(tile)}: the road leaves {_SIDE_WORD[port.side]} "
                                         f"of cell (col {port.cell[0]}, row {port.cell[1]}) into {what}")
        # a state (tile, entry) is viable if some way out leads to a viable state; prune until stable
        states = {(t.index, p) for t in self.tiles for p in t.ports}
        by_index = {t.index: t for t in self.tiles}
        changed = True
        while changed:
            changed = False
            for st in list(states):
                tile = by_index[st[0]]
                if not any((nxt := self.next_tile(tile, ex)) is not None and (nxt[0].index, nxt[1]) in states
                           for ex in self.exits(tile, st[1])):
                    states.discard(st)
                    changed = True
        self._viable = states

    def _start_cell(self, car: object, source: str) -> tuple[int, int]:
        first = self.tiles[0].cells[0]
        if car is None:
            return first
        if not isinstance(car, dict):
            raise MapError(f"{source}: car_pos is {type(car).__name__}, not an object with x and y")
        x = _number(car.get("x", first[0]), "car_pos.x", source)
        y = _number(car.get("y", first[1]), "car_pos.y", source)
        cell = (int(round(x)), int(round(y)))
        if cell not in self._cell_tile:
            self.warnings.append(f"car_pos (col {cell[0]}, row {cell[1]}) is not on a road; "
                                 f"starting at (col {first[0]}, row {first[1]})")
            return first
        return cell

    # --- geometry ----------------------------------------------------------------------
    @property
    def grid_origin(self) -> tuple[float, float]:
        return (-self.cols / 2.0, -self.rows / 2.0)

    def map_to_world(self, uv: np.ndarray) -> np.ndarray:
        """Grid units (cells from the grid centre, u east, v north) -> world metres."""
        return np.asarray(uv, dtype=np.float64) * self.cell_m

    def cell_centre(self, cell: tuple[int, int]) -> np.ndarray:
        return self.map_to_world(np.array([cell[0] + self.grid_origin[0], cell[1] + self.grid_origin[1]]))

    def cell_of(self, x: float, y: float) -> tuple[int, int]:
        return (int(round(x / self.cell_m + self.cols / 2)), int(round(y / self.cell_m + self.rows / 2)))

    def bounds_m(self, margin: float = 0.0) -> tuple[float, float, float, float]:
        """(xmin, ymin, xmax, ymax) in world metres of every tile's block (and the grid)."""
        cells = [c for t in self.tiles for c in t.footprint] + [(0, 0), (self.cols - 1, self.rows - 1)]
        c = np.array(cells, float) + np.array(self.grid_origin)
        lo, hi = (c.min(axis=0) - 0.5) * self.cell_m, (c.max(axis=0) + 0.5) * self.cell_m
        return lo[0] - margin, lo[1] - margin, hi[0] + margin, hi[1] + margin

    def tile_at(self, cell: tuple[int, int]) -> Tile | None:
        return self._cell_tile.get(cell)

    def centreline(self, tile: Tile, a: Port, b: Port) -> np.ndarray:
        """World-metre centreline (N,2) through a tile from port a to port b (cached)."""
        key = (tile.index, a, b)
        if key not in self._centrelines:
            self._centrelines[key] = self.map_to_world(tile_centreline(
                tile, a, b, self.grid_origin, self.style.turn_r_cells, self.style.chamfer))
        return self._centrelines[key]

    def exits(self, tile: Tile, entry: Port) -> list[Port]:
        return [p for p in tile.ports if p != entry]

    def viable_exits(self, tile: Tile, entry: Port) -> list[Port]:
        """Exits that do not lead into a dead end (the road can be followed on from there)."""
        return [p for p in self.exits(tile, entry) if self.leads_on(tile, p)]

    def leads_on(self, tile: Tile, port: Port) -> bool:
        """Leaving `tile` through `port`, can the road be followed for ever (no dead-end branch)?
        Roads are two-way, so this is also whether traffic ever arrives through that port."""
        nxt = self.next_tile(tile, port)
        return nxt is not None and (nxt[0].index, nxt[1]) in self._viable

    def next_tile(self, tile: Tile, exit_port: Port) -> tuple[Tile, Port] | None:
        """The tile and entry port beyond an exit, or None at a dead end."""
        other = self._cell_tile.get(exit_port.neighbour)
        back = Port(exit_port.neighbour, OPPOSITE[exit_port.side])
        if other is None or other is tile or back not in other.ports:
            return None
        return other, back

    def turn_of(self, entry: Port, exit_port: Port) -> str:
        """'straight', 'left' or 'right' for driving in through `entry` and out through `exit_port`."""
        if exit_port.side == OPPOSITE[entry.side]:
            return "straight"
        fu, fv = (-s for s in SIDES[entry.side])  # travel direction on entering
        eu, ev = SIDES[exit_port.side]
        return "left" if fu * ev - fv * eu > 0 else "right"  # v north: counter-clockwise = left

    def start_state(self) -> tuple[Tile, Port, Port, np.ndarray]:
        """Where VIA puts the car: the centre of the start cell, facing north. Returns the tile,
        the entry and exit of the path through that cell that runs nearest to north, and the
        start point in world metres (on the road's centre line)."""
        tile = self._cell_tile.get(self.start_cell) or self.tiles[0]
        start = self.cell_centre(self.start_cell)
        best = None
        for a in tile.ports:
            for b in self.exits(tile, a):
                pts = self.centreline(tile, a, b)
                i = int(np.argmin(np.hypot(*(pts - start).T)))
                d = pts[min(i + 1, len(pts) - 1)] - pts[max(i - 1, 0)]
                north = d[1] / max(float(np.hypot(*d)), 1e-9)
                viable = b in self.viable_exits(tile, a)
                score = (viable, round(north, 6), -float(np.hypot(*(pts[i] - start))))
                if best is None or score > best[0]:
                    best = (score, a, b, pts[i])
        return tile, best[1], best[2], best[3]

    def road_pieces(self) -> list[tuple[Tile, np.ndarray]]:
        """Every non-junction tile's centreline once (for painting)."""
        return [(t, self.centreline(t, t.ports[0], t.ports[1])) for t in self.tiles if not t.junction]


_SIDE_WORD = {"N": "north", "E": "east", "S": "south", "W": "west"}


def read_map(path: str | FsPath) -> object:
    """A map file's JSON, or MapError saying in one line why it cannot be read."""
    p = FsPath(path)
    try:
        return json.loads(p.read_text())
    except OSError as e:
        raise MapError(f"{p}: cannot read map file ({e.strerror or e})") from None
    except UnicodeDecodeError:
        raise MapError(f"{p}: not a text file") from None
    except json.JSONDecodeError as e:
        raise MapError(f"{p}: not valid JSON ({e.msg} at line {e.lineno})") from None
    except RecursionError:
        raise MapError(f"{p}: JSON nested too deeply") from None


def _where(tile: Tile) -> str:
    return (f"cell (col {tile.col}, row {tile.row}) [cell_datas[{tile.index}], tile_id "
            f"{tile.tile_id if tile.listed_id is None else tile.listed_id} {tile.name}, rot {tile.rot}]")


def _number(value: object, what: str, source: str) -> float:
    """A finite JSON number (or numeric string), else MapError naming the key."""
    if isinstance(value, bool) or not isinstance(value, (int, float, str)):
        raise MapError(f"{source}: {what} is {str(value)[:40]!r}, not a number")
    try:
        v = float(value)
    except (ValueError, OverflowError):
        raise MapError(f"{source}: {what} is {str(value)[:40]!r}, not a number") from None
    if not math.isfinite(v):
        raise MapError(f"{source}: {what} is {value!r}, not a finite number")
    return v


def _grid(data: object, source: str) -> tuple[int, int, list]:
    if not isinstance(data, dict):
        raise MapError(f"{source}: not a VIA map (the file holds a JSON {type(data).__name__}, not an object)")
    size, cells = data.get("map_size"), data.get("cell_datas")
    if not isinstance(size, dict) or "x" not in size or "y" not in size:
        raise MapError(f"{source}: not a VIA map (no map_size with x and y)")
    if not isinstance(cells, list):
        raise MapError(f"{source}: not a VIA map (no cell_datas list)")
    cols, rows = (_number(size[k], f"map_size.{k}", source) for k in "xy")
    if cols != int(cols) or rows != int(rows) or not (1 <= cols <= MAX_MAP_CELLS and 1 <= rows <= MAX_MAP_CELLS):
        raise MapError(f"{source}: map_size {size['x']}x{size['y']} is not a grid of 1 to {MAX_MAP_CELLS} "
                       "whole cells a side")
    return int(cols), int(rows), cells


def _tile(i: int, cd: object, cols: int, rows: int, source: str, warnings: list[str]) -> Tile:
    if not isinstance(cd, dict) or "id_inmap" not in cd or "tile_id" not in cd:
        raise MapError(f"{source}: cell_datas[{i}] is not an object with id_inmap and tile_id")
    idx = _number(cd["id_inmap"], f"cell_datas[{i}].id_inmap", source)
    tid = _number(cd["tile_id"], f"cell_datas[{i}].tile_id", source)
    rot = _number(cd.get("rot", 0), f"cell_datas[{i}].rot", source)
    if idx != int(idx) or idx < 0 or idx >= cols * rows:
        raise MapError(f"{source}: cell_datas[{i}].id_inmap {cd['id_inmap']} is not a cell of the "
                       f"{cols}x{rows} map (0 to {cols * rows - 1})")
    idx, listed = int(idx), int(tid)
    tile_id = listed if listed in LAYOUTS and listed == tid else 0
    col, row = idx % cols, idx // cols
    turned = int(round(rot / 90.0)) * 90
    where = f"cell_datas[{i}] at (col {col}, row {row})"
    if tile_id != listed or listed != tid:
        warnings.append(f"{where}: unknown tile_id {cd['tile_id']}, drawn as a straight (as VIA does)")
    if abs(turned - rot) > 1e-6:
        warnings.append(f"{where}: rot {cd.get('rot')} is not a multiple of 90; using {turned % 360}")
    return make_tile(i, tile_id, col, row, turned % 360, None if tile_id == listed else listed)


def _sign_from_via(track: Track, s: object, i: int, source: str) -> WorldObject | None:
    """A sign of VIA's: pos in cells from the grid centre, rot counter-clockwise with the face
    looking south at 0. On wider cells than VIA's the sign keeps its distance from the road."""
    if not isinstance(s, dict) or not isinstance(s.get("pos"), dict):
        raise MapError(f"{source}: sign_obj_datas[{i}] is not an object with sign_id and pos")
    sid = _number(s.get("sign_id"), f"sign_obj_datas[{i}].sign_id", source)
    u = _number(s["pos"].get("x"), f"sign_obj_datas[{i}].pos.x", source)
    v = _number(s["pos"].get("y"), f"sign_obj_datas[{i}].pos.y", source)
    rot = _number(s.get("rot", 0.0), f"sign_obj_datas[{i}].rot", source)
    if sid not in VIA_SIGN_NAMES:
        track.warnings.append(f"sign_obj_datas[{i}]: unknown sign_id {s.get('sign_id')}; left out")
        return None
    if abs(u) > 2 * track.cols or abs(v) > 2 * track.rows:
        track.warnings.append(f"sign_obj_datas[{i}]: pos ({u:g}, {v:g}) lies far outside the "
                              f"{track.cols}x{track.rows} map; left out")
        return None
    xy = np.array([u, v]) * VIA_CELL_M
    if track.cell_m != VIA_CELL_M:
        xy = _keep_roadside(track, xy)
    facing = math.radians(rot) - math.pi / 2
    return WorldObject(VIA_SIGN_NAMES[int(sid)], float(xy[0]), float(xy[1]), facing, seed=i)


def _keep_roadside(track: Track, xy_via: np.ndarray) -> np.ndarray:
    """Move a sign placed for VIA's 4 m cells onto this track's cells, at the same distance
    from the asphalt's edge (a sign stands a few metres beside the road whatever its width)."""
    k = track.cell_m / VIA_CELL_M
    best = None
    for t in track.tiles:
        for a in t.ports:
            for b in track.exits(t, a):
                pts = track.centreline(t, a, b) / k  # in VIA metres
                d = np.hypot(*(pts - xy_via).T)
                j = int(np.argmin(d))
                if best is None or d[j] < best[0]:
                    best = (float(d[j]), pts[j])
    dist, near = best
    beyond = max(dist - VIA_CELL_M / 2, 0.3)
    direction = (xy_via - near) / max(dist, 1e-9)
    return near * k + direction * (track.style.road_half_width + track.style.kerb_m + beyond)
