"""A route through a track: a chain of tile traversals with one continuous ego-lane path.

The path is the road centreline offset to the ego lane (right-hand traffic), sampled densely in
world metres, with arc length, heading and curvature per sample, so poses, ground truth and the
controller can look ahead along it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from signlane.angles import wrap_pi
from signlane.world.tiles import Port, Tile
from signlane.world.track import Track

# chooses an exit at a junction: (track, tile, entry, exits) -> exit
ExitPolicy = Callable[[Track, Tile, Port, list[Port]], Port]


@dataclass(frozen=True)
class Leg:
    tile: Tile
    entry: Port
    exit: Port
    s0: float  # arc length of the leg's start along the route (on the road centreline)
    turn: str  # straight | left | right (junctions); 'road' elsewhere


def random_policy(rng: np.random.Generator) -> ExitPolicy:
    """Any exit offered (routes offer only those that do not lead into a dead end)."""
    def choose(track, tile, entry, exits):
        return exits[int(rng.integers(len(exits)))]
    return choose


def straight_policy(track: Track, tile: Tile, entry: Port, exits: list[Port]) -> Port:
    for p in exits:
        if track.turn_of(entry, p) == "straight":
            return p
    return exits[0]


def _polyline_frame(pts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    d = np.diff(pts, axis=0)
    seg = np.hypot(d[:, 0], d[:, 1])
    s = np.concatenate([[0.0], np.cumsum(seg)])
    tang = np.gradient(pts, s, axis=0, edge_order=1)
    tang /= np.maximum(np.hypot(tang[:, 0], tang[:, 1]), 1e-12)[:, None]
    return s, tang


class Route:
    """A route of `legs`; `centre` is the road centreline, `lane` the ego-lane centre path."""

    def __init__(self, track: Track, legs: list[Leg], centre: np.ndarray, closed: bool):
        self.track = track
        self.legs = legs
        self.closed = closed
        self.centre = centre
        s, tang = _polyline_frame(centre)
        self.s = s
        self.tangent = tang
        self.heading = np.unwrap(np.arctan2(tang[:, 1], tang[:, 0]))
        # curvature: positive when bending right (heading decreasing, since headings are CCW)
        self.curvature = -np.gradient(self.heading, s)
        self.right = np.column_stack([tang[:, 1], -tang[:, 0]])
        self.lane_offset = track.style.ego_lane_offset()
        self.lane = centre + self.lane_offset * self.right
        self.start_s = 0.0  # arc length of the car's start (the start cell's centre), when on the route

    @property
    def length(self) -> float:
        """Route length in metres; a closed route includes the segment back to its start."""
        if self.closed:
            return float(self.s[-1] + np.hypot(*(self.centre[0] - self.centre[-1])))
        return float(self.s[-1])

    @classmethod
    def drive(cls, track: Track, length_m: float, policy: ExitPolicy = straight_policy,
              reverse: bool = False) -> "Route":
        """Follow the road from the start cell for at least length_m, choosing exits by policy."""
        return cls._walk(track, policy, length_m, reverse, stop_at_start=False)

    @classmethod
    def loop(cls, track: Track, policy: ExitPolicy = straight_policy, reverse: bool = False) -> "Route":
        """One lap: follow the road from the start until the start leg comes round again."""
        return cls._walk(track, policy, math.inf, reverse, stop_at_start=True)

    @classmethod
    def _walk(cls, track: Track, policy: ExitPolicy, length_m: float, reverse: bool,
              stop_at_start: bool, max_legs: int = 20000) -> "Route":
        """Follow the road from where VIA starts the car (world/track.py start_state), choosing
        among exits that do not lead into a dead end; a route that meets a dead end stops there."""
        tile, entry, exit_, start_xy = track.start_state()
        state = (tile, exit_ if reverse else entry)
        steps: list[tuple[Tile, Port, Port]] = []
        seen: dict = {}
        total = 0.0
        for _ in range(max_legs):
            if stop_at_start and state in seen:
                # a lap is the cycle the walk fell into (the start may lead into it)
                return cls._from_steps(track, steps[seen[state]:], closed=True, start_xy=start_xy)
            seen[state] = len(steps)
            t, e = state
            exits = track.viable_exits(t, e) or track.exits(t, e)
            if not exits:
                break
            out = exits[0] if len(exits) == 1 else policy(track, t, e, exits)
            steps.append((t, e, out))
            total += float(np.hypot(*np.diff(track.centreline(t, e, out), axis=0).T).sum())
            nxt = track.next_tile(t, out)
            if nxt is None or (not stop_at_start and total >= length_m):
                if stop_at_start:
                    raise RuntimeError(f"{track.name}: the road from the start ends at a dead end "
                                       "before it closes into a loop")
                return cls._from_steps(track, steps, closed=False, start_xy=start_xy)
            state = nxt
        raise RuntimeError("the route did not close (or reach its length) within "
                           f"{max_legs} tiles with this exit policy")

    @classmethod
    def _from_steps(cls, track: Track, steps: list, closed: bool, start_xy=None) -> "Route":
        legs, pieces, s0 = [], [], 0.0
        for t, e, out in steps:
            pts = track.centreline(t, e, out)
            legs.append(Leg(t, e, out, s0, track.turn_of(e, out) if t.junction else "road"))
            pieces.append(pts if not pieces else pts[1:])
            s0 += float(np.hypot(*np.diff(pts, axis=0).T).sum())
        centre = np.concatenate(pieces)
        if closed:
            centre = centre[:-1]  # the last point repeats the first
        route = cls(track, legs, centre, closed)
        if start_xy is not None and route.legs[0].tile is track.tile_at(track.start_cell):
            route.start_s = float(route.project(*start_xy)[0])
        return route

    # --- queries ------------------------------------------------------------------------
    def index_at(self, s: float) -> int:
        if self.closed:
            s = s % self.length
        return int(np.clip(np.searchsorted(self.s, s), 0, len(self.s) - 1))

    def pose_at(self, s: float, lateral_m: float = 0.0, heading_offset: float = 0.0) -> "Pose":
        """Car pose at arc length s, lateral_m right of the ego-lane centre, heading offset
        (radians, positive = pointing right of the lane direction)."""
        i, j, t = self._bracket(s)
        lane = self.lane[i] * (1 - t) + self.lane[j] * t
        right = self.right[i] * (1 - t) + self.right[j] * t
        right /= max(float(np.hypot(*right)), 1e-12)
        heading = self.heading[i] + t * wrap_pi(self.heading[j] - self.heading[i])
        p = lane + lateral_m * right
        return Pose(float(p[0]), float(p[1]), float(heading - heading_offset))

    def _bracket(self, s: float) -> tuple[int, int, float]:
        """Samples i, j around arc length s and the fraction t of the way from i to j."""
        if self.closed:
            s = s % self.length
        n = len(self.s)
        j = int(np.searchsorted(self.s, s, side="right"))
        if j >= n:  # past the last sample: on a closed route, the closing segment
            if not self.closed:
                return n - 1, n - 1, 0.0
            seg = self.length - self.s[-1]
            return n - 1, 0, float(np.clip((s - self.s[-1]) / max(seg, 1e-9), 0, 1))
        i = max(j - 1, 0)
        seg = self.s[j] - self.s[i]
        return i, j, float(np.clip((s - self.s[i]) / seg, 0, 1)) if seg > 0 else 0.0

    def ahead(self, s: float, dist: float) -> slice | np.ndarray:
        """Indices of samples from s to s+dist (wrapping on closed routes)."""
        i0 = self.index_at(s)
        if self.closed:
            n = len(self.s)
            step = self.length / max(n - 1, 1)
            count = int(dist / max(step, 1e-6))
            return (i0 + np.arange(count)) % n
        i1 = int(np.searchsorted(self.s, self.s[i0] + dist))
        return np.arange(i0, min(i1, len(self.s)))

    def leg_at(self, s: float) -> Leg:
        if self.closed:
            s = s % self.length
        starts = [leg.s0 for leg in self.legs]
        return self.legs[max(0, int(np.searchsorted(starts, s, side="right")) - 1)]

    def project(self, x: float, y: float, s_hint: float | None = None, window: float = 30.0) -> tuple[float, float]:
        """Nearest point on the ego-lane path: (arc length s, signed lateral metres, + = right)."""
        if s_hint is None:
            idx = np.arange(len(self.s))
        else:
            idx = self.ahead(s_hint - window / 2, window)
        p = np.array([x, y])
        d = self.lane[idx] - p
        j = int(idx[int(np.argmin(np.einsum("ij,ij->i", d, d)))])
        n = len(self.s)
        best = (np.inf, float(self.s[j]), 0.0)
        # refine on the two segments around the nearest sample
        for a, b in ((j - 1, j), (j, j + 1)):
            if not self.closed and (a < 0 or b >= n):
                continue
            a, b = a % n, b % n
            seg = self.lane[b] - self.lane[a]
            t = float(np.clip(np.dot(p - self.lane[a], seg) / max(np.dot(seg, seg), 1e-12), 0.0, 1.0))
            q = self.lane[a] + t * seg
            dist = float(np.hypot(*(p - q)))
            if dist < best[0]:
                ds = (self.length - self.s[a]) if b < a else (self.s[b] - self.s[a])
                right = self.right[a] * (1 - t) + self.right[b] * t
                best = (dist, float(self.s[a] + t * ds), float(np.dot(p - q, right / np.hypot(*right))))
        return best[1], best[2]


@dataclass(frozen=True)
class Pose:
    """Car pose in world metres; heading radians CCW from +x (east)."""

    x: float
    y: float
    heading: float

    @property
    def forward(self) -> np.ndarray:
        return np.array([math.cos(self.heading), math.sin(self.heading)])

    @property
    def right(self) -> np.ndarray:
        return np.array([math.sin(self.heading), -math.cos(self.heading)])

    def world_to_ground_a(self) -> np.ndarray:
        """3x3 affine: world (X, Y, 1) -> car ground (x_right, y_fwd, 1)."""
        r, f = self.right, self.forward
        p = np.array([self.x, self.y])
        return np.array([[r[0], r[1], -r @ p], [f[0], f[1], -f @ p], [0.0, 0.0, 1.0]])

    def ground_to_world_a(self) -> np.ndarray:
        r, f = self.right, self.forward
        return np.array([[r[0], f[0], self.x], [r[1], f[1], self.y], [0.0, 0.0, 1.0]])

    def to_ground(self, xy_world: np.ndarray) -> np.ndarray:
        xy = np.asarray(xy_world, dtype=np.float64).reshape(-1, 2)
        a = self.world_to_ground_a()
        return xy @ a[:2, :2].T + a[:2, 2]
