"""Track model: a VIA-style grid of road tiles in world metres, its signs and distractors.

World frame: metres, x east (map columns), y north (map rows go south), headings in radians
counter-clockwise from +x. Procedural tracks are generated as VIA map dicts (world/procedural.py)
so both go through `Track.from_via`.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path as FsPath

import numpy as np

from signlane.world.art import VIA_SIGN_IDS as VIA_SIGN_NAMES
from signlane.world.tiles import OPPOSITE, SIDES, Port, Tile, make_tile, tile_centreline



class MapError(ValueError):
    """A map file that cannot be turned into a drivable track."""


@dataclass(frozen=True)
class RoadStyle:
    """Road geometry and paint. Widths in metres."""

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

    @property
    def road_half_width(self) -> float:
        return self.lanes * self.lane_width / 2 + self.shoulder

    def ego_lane_offset(self) -> float:
        """Ego-lane centre, metres right of the road centreline (right-hand traffic)."""
        return self.lane_width / 2 if self.lanes == 2 else 0.0


@dataclass(frozen=True)
class WorldObject:
    """A sign or distractor standing in the world. facing = direction its face points (rad)."""

    kind: str  # sign class name, or a distractor kind from world.art
    x: float
    y: float
    facing: float
    size_m: float = 0.9  # face height (and width, for square faces)
    height_m: float = 1.8  # height of the face centre above the ground
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
    _cell_tile: dict[tuple[int, int], Tile] = field(default_factory=dict, repr=False)
    _centrelines: dict[tuple[int, Port, Port], np.ndarray] = field(default_factory=dict, repr=False)

    # --- construction ----------------------------------------------------------------
    @classmethod
    def from_via(cls, data: dict, cell_m: float = 12.0, style: RoadStyle | None = None,
                 source: str = "map") -> "Track":
        """Build a track from a VIA map dict; raises MapError naming the first broken cell."""
        try:
            cols, rows = int(data["map_size"]["x"]), int(data["map_size"]["y"])
            cells = data["cell_datas"]
        except (KeyError, TypeError, ValueError) as e:
            raise MapError(f"{source}: not a VIA map (missing or bad key {e})") from None
        tiles: list[Tile] = []
        owner: dict[tuple[int, int], Tile] = {}
        for i, cd in enumerate(cells):
            try:
                idx, tid, rot = int(cd["id_inmap"]), int(cd["tile_id"]), int(cd.get("rot", 0))
                tile = make_tile(i, tid, idx % cols, idx // cols, rot)
            except (KeyError, TypeError, ValueError) as e:
                raise MapError(f"{source}: cell_datas[{i}] is invalid: {e}") from None
            for c in tile.cells:
                if not (0 <= c[0] < cols and 0 <= c[1] < rows):
                    raise MapError(f"{source}: {_where(tile)} covers cell {c} outside the "
                                   f"{cols}x{rows} map")
                if c in owner:
                    raise MapError(f"{source}: {_where(tile)} overlaps {_where(owner[c])} at cell {c}")
                owner[c] = tile
            tiles.append(tile)
        if not tiles:
            raise MapError(f"{source}: the map has no road cells")
        track = cls(str(data.get("map_name", source)), cols, rows, float(cell_m), tiles,
                    style=style or RoadStyle(), _cell_tile=owner)
        track._check_connected(source)
        track.signs = [_sign_from_via(track, s, i, source) for i, s in
                       enumerate(data.get("sign_obj_datas", []) or [])]
        track.distractors = [WorldObject(**d) for d in data.get("signlane_distractors", [])]
        car = data.get("car_pos") or {}
        start = (int(round(float(car.get("x", tiles[0].col)))), int(round(float(car.get("y", tiles[0].row)))))
        track.start_cell = start if start in owner else (tiles[0].cells[0])
        return track

    @classmethod
    def load(cls, path: str | FsPath, **kw) -> "Track":
        p = FsPath(path)
        try:
            data = json.loads(p.read_text())
        except OSError as e:
            raise MapError(f"{p}: cannot read map file ({e.strerror})") from None
        except json.JSONDecodeError as e:
            raise MapError(f"{p}: not valid JSON ({e.msg} at line {e.lineno})") from None
        return cls.from_via(data, source=str(p), **kw)

    def _check_connected(self, source: str) -> None:
        for tile in sorted(self.tiles, key=lambda t: (t.row, t.col)):
            for port in tile.ports:
                other = self._cell_tile.get(port.neighbour)
                back = Port(port.neighbour, OPPOSITE[port.side])
                if other is None or back not in other.ports:
                    what = "no road" if other is None else f"a {other.name} tile with no road entering from the {OPPOSITE[port.side]}"
                    raise MapError(f"{source}: {_where(tile)}: road leaves {_SIDE_WORD[port.side]} "
                                   f"at cell (col {port.cell[0]}, row {port.cell[1]}) into cell "
                                   f"(col {port.neighbour[0]}, row {port.neighbour[1]}), which has {what}")

    # --- geometry ----------------------------------------------------------------------
    @property
    def grid_origin(self) -> tuple[float, float]:
        return (-self.cols / 2.0, -self.rows / 2.0)

    def map_to_world(self, uv: np.ndarray) -> np.ndarray:
        uv = np.asarray(uv, dtype=np.float64)
        return np.column_stack([uv[..., 0] * self.cell_m, -uv[..., 1] * self.cell_m])

    def bounds_m(self, margin: float = 0.0) -> tuple[float, float, float, float]:
        """(xmin, ymin, xmax, ymax) of the grid in world metres."""
        ox, oy = self.grid_origin
        x0, x1 = (ox - 0.5) * self.cell_m, (ox + self.cols - 0.5) * self.cell_m
        y0, y1 = -(oy + self.rows - 0.5) * self.cell_m, -(oy - 0.5) * self.cell_m
        return x0 - margin, y0 - margin, x1 + margin, y1 + margin

    def tile_at(self, cell: tuple[int, int]) -> Tile | None:
        return self._cell_tile.get(cell)

    def centreline(self, tile: Tile, a: Port, b: Port) -> np.ndarray:
        """World-metre centreline (N,2) through a tile from port a to port b (cached)."""
        key = (tile.index, a, b)
        if key not in self._centrelines:
            self._centrelines[key] = self.map_to_world(tile_centreline(tile, a, b, self.grid_origin))
        return self._centrelines[key]

    def exits(self, tile: Tile, entry: Port) -> list[Port]:
        return [p for p in tile.ports if p != entry]

    def next_tile(self, tile: Tile, exit_port: Port) -> tuple[Tile, Port]:
        other = self._cell_tile[exit_port.neighbour]
        return other, Port(exit_port.neighbour, OPPOSITE[exit_port.side])

    def turn_of(self, entry: Port, exit_port: Port) -> str:
        """'straight', 'left' or 'right' for driving in through `entry` and out through `exit_port`."""
        if exit_port.side == OPPOSITE[entry.side]:
            return "straight"
        fu, fv = (-s for s in SIDES[entry.side])  # travel direction on entering
        eu, ev = SIDES[exit_port.side]
        cross = fu * ev - fv * eu  # v points down the map: positive cross = clockwise = right
        return "right" if cross > 0 else "left"

    def road_pieces(self) -> list[tuple[Tile, np.ndarray]]:
        """Every non-junction tile's centreline once (for painting)."""
        out = []
        for t in self.tiles:
            if not t.junction:
                out.append((t, self.centreline(t, t.ports[0], t.ports[1])))
        return out


_SIDE_WORD = {"N": "north", "E": "east", "S": "south", "W": "west"}


def _where(tile: Tile) -> str:
    return (f"cell (col {tile.col}, row {tile.row}) [cell_datas[{tile.index}], tile_id {tile.tile_id} "
            f"{tile.name}, rot {tile.rot}]")


def _sign_from_via(track: Track, s: dict, i: int, source: str) -> WorldObject:
    try:
        sid = int(s["sign_id"])
        name = VIA_SIGN_NAMES[sid]
        u, v = float(s["pos"]["x"]), float(s["pos"]["y"])
        rot = float(s.get("rot", 0.0))
    except (KeyError, TypeError, ValueError) as e:
        raise MapError(f"{source}: sign_obj_datas[{i}] is invalid ({e})") from None
    xy = track.map_to_world(np.array([[u, v]]))[0]
    # rot: the direction the sign faces, clockwise on the map from north
    facing = math.pi / 2 - math.radians(rot)
    return WorldObject(name, float(xy[0]), float(xy[1]), facing, seed=i)
