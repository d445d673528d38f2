"""Where the car is on the road network, and what the rules asked of it: the simulator's referee.

The car picks its own exits, so there is no fixed route: the tracker follows it tile by tile
(entering through a port, leaving through another), measures cross-track error against the ego
lane of the paths the current tile allows, and records junction turns against the sign on that
approach, stops at stop signs, off-road events and laps.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from signlane.world.tiles import SIDES, Port, Tile
from signlane.world.track import Track, WorldObject

TURN_RULES = {"left": lambda t: t == "left", "right": lambda t: t == "right", "straight": lambda t: t == "straight",
              "no_left": lambda t: t != "left", "no_right": lambda t: t != "right"}
STOP_ZONE_M = (0.0, 12.0)  # a full stop counts when the car is this far before the sign
STOPPED_SPEED = 0.05  # m/s: a full stop
STOP_HOLD_S = 2.0
APPROACH_M = 24.0  # a sign up to this far before a junction's edge is for that junction
BESIDE_M = 7.0  # signs stand up to this far beyond the road's edge (VIA's editor: 1.6-4.5 m)


@dataclass
class StopWatch:
    sign: WorldObject
    stopped_since: float | None = None
    complied: bool = False
    active: bool = False


@dataclass
class CourseLog:
    junctions: list[dict] = field(default_factory=list)
    stops: list[dict] = field(default_factory=list)


def _polyline_offset(pts: np.ndarray, p: np.ndarray) -> tuple[float, float]:
    """(distance, signed lateral + right of travel) from p to a polyline, and arc position."""
    a, b = pts[:-1], pts[1:]
    ab = b - a
    t = np.clip(np.einsum("ij,ij->i", p - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-12), 0, 1)
    q = a + t[:, None] * ab
    d = np.hypot(*(p - q).T)
    i = int(np.argmin(d))
    cross = ab[i, 0] * (p[1] - a[i, 1]) - ab[i, 1] * (p[0] - a[i, 0])
    # CCW cross > 0 = left of travel; a point dead ahead of the path's end (cross 0) is still
    # its distance away: no sign must not make it 0
    return float(d[i]), float(d[i]) if cross < 0 else -float(d[i])


def _pose_on(pts: np.ndarray, i: int) -> tuple[float, float, float]:
    """(x, y, heading) at point i of a path, the heading along it there."""
    j = min(i + 1, len(pts) - 1)
    k = max(j - 1, 0)
    return float(pts[i][0]), float(pts[i][1]), math.atan2(*(pts[j] - pts[k])[::-1])


class CourseTracker:
    def __init__(self, track: Track, tile: Tile, entry: Port):
        self.track = track
        self.lane_w = track.style.lane_width
        self.tile, self.entry = tile, entry
        self.approach_signs = self._approach_signs()
        self.stops = [StopWatch(s) for s in track.signs if s.kind == "stop"]
        self.log = CourseLog()
        self.visited = {(tile.index, entry.side)}
        self.laps = 0
        self.offroad = False
        self._lanes: dict = {}
        self._left_by: tuple | None = None

    # --- geometry -------------------------------------------------------------------------
    def cell_of(self, x: float, y: float) -> tuple[int, int]:
        return self.track.cell_of(x, y)

    def lane_path(self, tile: Tile, entry: Port, exit_port: Port) -> np.ndarray:
        key = (tile.index, entry, exit_port)
        if key not in self._lanes:
            c = self.track.centreline(tile, entry, exit_port)
            d = np.gradient(c, axis=0)
            d /= np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-12)[:, None]
            right = np.column_stack([d[:, 1], -d[:, 0]])
            self._lanes[key] = c + self.track.style.ego_lane_offset() * right
        return self._lanes[key]

    def cross_track(self, x: float, y: float) -> float:
        """Signed metres from the nearest ego-lane path through the current tile (+ right)."""
        best = (math.inf, 0.0)
        for ex in self.track.exits(self.tile, self.entry):
            d, lat = _polyline_offset(self.lane_path(self.tile, self.entry, ex), np.array([x, y]))
            best = min(best, (d, lat))
        return best[1]

    def put_back_pose(self, x: float, y: float) -> tuple[float, float, float]:
        """Where the referee puts a car that left the road at (x, y): the closest point on the
        current tile's ego-lane paths, with the heading there. A car that drove off a dead end is
        turned round at the road's end instead, in the lane that leads back out, as a safety
        driver would (the tracker enters the tile anew from that end): put back facing the end it
        would drive off again at once, and one wrong turn would count as an off-road event every
        few frames for the rest of the run."""
        left_by = self._left_by
        if left_by is not None and left_by[0] == self.tile.index and self.track.next_tile(self.tile, left_by[1]) is None:
            end = left_by[1]
            self.entry, self._left_by = end, None
            ex = (self.track.viable_exits(self.tile, end) or self.track.exits(self.tile, end))[0]
            return _pose_on(self.lane_path(self.tile, end, ex), 0)
        best = None
        for ex in self.track.exits(self.tile, self.entry):
            pts = self.lane_path(self.tile, self.entry, ex)
            i = int(np.argmin(np.hypot(*(pts - (x, y)).T)))
            d = float(np.hypot(*(pts[i] - (x, y))))
            if best is None or d < best[0]:
                best = (d, _pose_on(pts, i))
        return best[1]

    # --- signs ------------------------------------------------------------------------------
    def _approach_signs(self) -> dict[tuple[int, str], str]:
        """(junction tile, entry side) -> the turn sign standing on that approach: facing its
        traffic, beside the road, between the junction's centre and APPROACH_M before its edge."""
        out = {}
        reach = self.track.style.road_half_width + self.track.style.kerb_m + BESIDE_M
        for tile in self.track.tiles:
            if not tile.junction:
                continue
            centre = self.track.cell_centre((tile.col, tile.row))
            for port in tile.ports:
                side = np.array(SIDES[port.side], float)
                edge = self.track.cell_centre(port.cell) + 0.5 * side * self.track.cell_m
                inward = -side  # travel direction into the tile
                arm = float((edge - centre) @ side)
                for s in self.track.signs:
                    if s.kind not in TURN_RULES:
                        continue
                    rel = np.array([s.x, s.y]) - edge
                    back = -float(rel @ inward)  # metres before the edge
                    facing = np.array([math.cos(s.facing), math.sin(s.facing)])
                    if -arm < back < APPROACH_M and abs(float(rel @ [inward[1], -inward[0]])) < reach \
                            and facing @ inward < -0.5:
                        out[(tile.index, port.side)] = s.kind
        return out

    # --- per frame -----------------------------------------------------------------------------
    def update(self, t: float, x: float, y: float, heading: float, speed: float) -> float:
        """Advance the tracker to the car's pose; returns the cross-track error in metres."""
        cell = self.cell_of(x, y)
        if cell not in self.tile.cells:
            self._leave(t, cell, x, y)
        self._watch_stops(t, x, y, heading, speed)
        return self.cross_track(x, y)

    def _leave(self, t: float, cell: tuple[int, int], x: float, y: float) -> None:
        ports = [p for p in self.track.exits(self.tile, self.entry) if p.neighbour == cell]
        if not ports:
            return  # off the road network or cutting a corner: stay until it enters a neighbour
        exit_port = ports[0]
        nxt = self.track.next_tile(self.tile, exit_port)
        if nxt is None and self._left_by == (self.tile.index, exit_port):
            return  # already logged: the car is past the end of the road
        self._left_by = (self.tile.index, exit_port)
        if self.tile.junction:
            turn = self.track.turn_of(self.entry, exit_port)
            sign = self.approach_signs.get((self.tile.index, self.entry.side))
            dead = not self.track.leads_on(self.tile, exit_port)
            ok = (TURN_RULES[sign](turn) if sign else None) if not dead else False
            self.log.junctions.append({"t": round(t, 2), "cell": [self.tile.col, self.tile.row], "turn": turn,
                                       "sign": sign, "complied": ok, "dead_end": dead})
        if nxt is None:
            return  # the road ends here: the car leaves it (an off-road event follows)
        self.tile, self.entry = nxt
        state = (self.tile.index, self.entry.side)
        if state in self.visited:
            self.laps += 1
            self.visited = set()
        self.visited.add(state)

    def _watch_stops(self, t: float, x: float, y: float, heading: float, speed: float) -> None:
        fwd = np.array([math.cos(heading), math.sin(heading)])
        for w in self.stops:
            s = w.sign
            facing = np.array([math.cos(s.facing), math.sin(s.facing)])
            rel = np.array([x - s.x, y - s.y])
            u = float(rel @ facing)  # metres in front of the sign's face
            lateral = abs(float(rel @ [facing[1], -facing[0]]))
            near = lateral < self.track.style.road_half_width + self.track.style.kerb_m + BESIDE_M
            approaching = facing @ fwd < -0.5 and near
            if approaching and 0 < u < 30:
                w.active = True
                in_zone = STOP_ZONE_M[0] <= u <= STOP_ZONE_M[1]
                if in_zone and speed < STOPPED_SPEED:
                    w.stopped_since = t if w.stopped_since is None else w.stopped_since
                    if t - w.stopped_since >= STOP_HOLD_S:
                        w.complied = True
                else:
                    w.stopped_since = None
            elif w.active and u <= 0 and near:
                self.log.stops.append({"t": round(t, 2), "sign": [round(s.x, 2), round(s.y, 2)],
                                       "complied": w.complied})
                w.active, w.complied, w.stopped_since = False, False, None
            elif w.active and u >= 30:
                w.active, w.complied, w.stopped_since = False, False, None
