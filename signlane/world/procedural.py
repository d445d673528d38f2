"""Seeded procedural road networks, emitted as VIA map dicts in VIA's own conventions (so one
loader serves both, and a procedural map opens in VIA's editor as it drives here).

A network is a coarse grid of nodes joined by straight roads; the node set comes from a random
block shape (a polyomino), some inner roads are dropped, and no node is left a dead end. Each
node becomes a tile by its degree: crossing (4), T-junction (3, VIA's 2x3 block), straight
(2, through) or a quarter turn of 2x2 or 4x4 cells (2, corner). A lane shift moves a road one
cell sideways on its way to the next node (that node and the ones beyond it move with it). Some
maps get dead ends as VIA's editor makes them: a T-junction whose arm leads nowhere. Signs
stand before junctions (never sending the car into a dead end) and now and then on plain road.
"""
from __future__ import annotations

import math

import numpy as np

from signlane.world.tiles import OPPOSITE, SIDES, rotate_side, rotate_step

TURN_ROT = {frozenset("SW"): 0, frozenset("ES"): 90, frozenset("NE"): 180, frozenset("WN"): 270}
TEE_ROT = {"W": 0, "S": 90, "E": 180, "N": 270}  # keyed by the side without road
SIGN_IDS = {"left": 0, "no_left": 1, "right": 2, "no_right": 3, "stop": 4, "straight": 5}
VIA_M = 4.0  # signs are placed in VIA's metres (cells of 4 m), beside VIA's 4 m carriageway


def sign_sight_m(beside_m: float) -> float:
    """Straight road a sign needs before it to be read: VIA's camera (75 degrees across) sees a
    sign beside_m beyond the asphalt from about 1.3 times its distance to the side ahead, and a
    few metres more of it give the classifier its frames."""
    return 8.0 + 1.3 * (ROAD_HALF_M + KERB_M + beside_m)
ROAD_HALF_M, KERB_M = 2.0, 0.18


def _blocks(rng: np.random.Generator, bc: int, br: int) -> set[tuple[int, int]]:
    """A random 4-connected, hole-free set of blocks inside a bc x br grid."""
    blocks = {(i, j) for i in range(bc) for j in range(br)}
    for _ in range(int(rng.integers(0, max(1, bc * br // 2)))):
        cand = sorted(blocks)[int(rng.integers(len(blocks)))]
        trial = blocks - {cand}
        if len(trial) >= 1 and _connected(trial) and _hole_free(trial, bc, br):
            blocks = trial
    return blocks


def _connected(cells: set[tuple[int, int]]) -> bool:
    if not cells:
        return False
    seen, todo = set(), [next(iter(cells))]
    while todo:
        c = todo.pop()
        if c in seen:
            continue
        seen.add(c)
        todo += [(c[0] + du, c[1] + dv) for du, dv in SIDES.values() if (c[0] + du, c[1] + dv) in cells]
    return seen == cells


def _hole_free(blocks: set[tuple[int, int]], bc: int, br: int) -> bool:
    outside = {(i, j) for i in range(-1, bc + 1) for j in range(-1, br + 1)} - blocks
    return _connected(outside)


def _network(rng: np.random.Generator, bc: int, br: int) -> dict[tuple[int, int], set[str]]:
    """Node (i east, j north) -> set of sides with a road; inner edges dropped at random."""
    blocks = _blocks(rng, bc, br)
    edges: dict[frozenset, int] = {}  # edge -> number of blocks it borders
    for (i, j) in blocks:
        corners = [(i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)]
        for a, b in zip(corners, corners[1:] + corners[:1]):
            e = frozenset((a, b))
            edges[e] = edges.get(e, 0) + 1
    keep = set(edges)
    inner = sorted((e for e, n in edges.items() if n == 2), key=lambda e: sorted(e))
    rng.shuffle(inner)
    for e in inner:
        if rng.random() < 0.25 and _ok_without(keep, e):
            keep.discard(e)
    nodes: dict[tuple[int, int], set[str]] = {}
    for e in sorted(keep, key=lambda e: sorted(e)):
        a, b = sorted(e)
        side = "E" if b[0] > a[0] else "N"
        nodes.setdefault(a, set()).add(side)
        nodes.setdefault(b, set()).add(OPPOSITE[side])
    return nodes


def _ok_without(keep: set, e: frozenset) -> bool:
    rest = keep - {e}
    deg: dict = {}
    for x in rest:
        for n in x:
            deg[n] = deg.get(n, 0) + 1
    if any(d == 1 for d in deg.values()) or any(n not in deg for n in e):
        return False
    adj: dict = {}
    for x in rest:
        a, b = tuple(x)
        adj.setdefault(a, []).append(b)
        adj.setdefault(b, []).append(a)
    seen, todo = set(), [min(adj)]
    while todo:
        n = todo.pop()
        if n not in seen:
            seen.add(n)
            todo += adj[n]
    return len(seen) == len(adj)


class _Builder:
    """Tiles by pivot cell, the cells each covers, and the cells a node tile reaches along a side."""

    def __init__(self):
        self.tiles: dict[tuple[int, int], tuple[int, int]] = {}  # pivot -> (tile_id, rot)
        self.used: set[tuple[int, int]] = set()

    def put(self, pivot: tuple[int, int], tile_id: int, rot: int, cells) -> None:
        cells = set(cells)
        if cells & self.used:
            raise AssertionError(f"tiles overlap at {sorted(cells & self.used)}")  # spacing prevents it
        self.tiles[pivot] = (tile_id, rot)
        self.used |= cells


def _add(c: tuple[int, int], off: tuple[int, int]) -> tuple[int, int]:
    return c[0] + off[0], c[1] + off[1]


def _reach(sides: set[str], stub: str | None, turn: int | None) -> int:
    """How many cells a node's tile covers along each of its roads, beyond the node's cell."""
    if stub is not None or len(sides) == 3:
        return 1  # a T-junction's arms
    return turn - 1 if turn else 0


def _node_tile(b: _Builder, c: tuple[int, int], sides: set[str], stub: str | None, k: int | None) -> None:
    """Place a node's tile at cell c. `stub`: a corner node becomes a T-junction with a dead-end
    arm on that side instead; `k`: a corner's turn size (2 or 4)."""
    if stub is not None:
        sides = sides | {stub}
    if len(sides) == 4:
        b.put(c, 1, 0, [c])
        return
    if len(sides) == 3:
        rot = TEE_ROT[({"N", "E", "S", "W"} - sides).pop()]
        arms = [_add(c, rotate_step(o, rot)) for o in ((0, -1), (0, 1), (1, 0))]
        corners = [_add(c, rotate_step(o, rot)) for o in ((1, -1), (1, 1))]
        b.put(c, 4, rot, [c] + arms + corners)
        return
    if OPPOSITE[min(sides)] in sides:
        b.put(c, 0, 0 if "N" in sides else 90, [c])
        return
    rot = TURN_ROT[frozenset(sides)]
    corner = (1, 1) if k == 4 else (0, 0)  # the corner cell (where the two roads' lines cross) at rot 0
    du, dv = rotate_step(corner, rot)
    pivot = (c[0] - du, c[1] - dv)
    block = [(pivot[0] + x, pivot[1] + y) for x, y in
             (rotate_step((a, bb), rot) for a in range(-(k // 2), k - k // 2) for bb in range(-(k // 2), k - k // 2))]
    b.put(pivot, 2 if k == 2 else 3, rot, block)


def _shift_tile(b: _Builder, start: tuple[int, int], side: str, rng: np.random.Generator) -> None:
    """A lane shift entered at cell `start` travelling towards `side` (N or E), at either of its
    two rotations for that direction (VIA's shift moves east going north, south going east)."""
    if side == "N":
        rot = 0 if rng.random() < 0.5 else 180
        pivot = (start[0], start[1] + 1) if rot == 0 else (start[0] + 1, start[1])
        cells = [start, (start[0], start[1] + 1), (start[0] + 1, start[1]), (start[0] + 1, start[1] + 1)]
    else:
        rot = 90 if rng.random() < 0.5 else 270
        pivot = (start[0], start[1] - 1) if rot == 90 else (start[0] + 1, start[1])
        cells = [start, (start[0] + 1, start[1]), (start[0], start[1] - 1), (start[0] + 1, start[1] - 1)]
    b.put(pivot, 5, rot, cells)


def generate_map(seed: int, name: str | None = None, size: str = "medium", sign_prob: float = 0.8,
                 distractors_per_cell: float = 0.08, shift_prob: float = 0.25,
                 dead_end_prob: float = 0.25) -> dict:
    """A VIA map dict for a seeded random road network (plus `signlane_*` keys VIA ignores)."""
    rng = np.random.default_rng(seed)
    if size not in ("small", "medium", "large"):
        raise ValueError(f"size must be small, medium or large, not {size!r}")
    bc, br = {"small": (1, 1), "medium": (2, int(rng.integers(1, 3))), "large": (3, int(rng.integers(2, 4)))}[size]
    nodes = _network(rng, bc, br)
    spacing = [int(rng.integers(8, 12)) for _ in range(max(bc, br) + 1)]
    stubs = _choose_stubs(rng, nodes, dead_end_prob)
    turns = {n: (4 if rng.random() < 0.5 else 2) for n, s in sorted(nodes.items())
             if len(s) == 2 and OPPOSITE[min(s)] not in s and n not in stubs}
    reach = {n: {s: _reach(nodes[n], stubs.get(n), turns.get(n)) for s in nodes[n]} for n in nodes}
    xs = np.concatenate([[0], np.cumsum(spacing[:bc])])
    ys = np.concatenate([[0], np.cumsum(spacing[:br])])
    # a lane shift on a segment moves the node at its far end (and those beyond) one cell over;
    # only where the segment has room left between its two node tiles
    def room(n, s, length):
        m = (n[0] + (s == "E"), n[1] + (s == "N"))
        return length - 2 - reach[n][s] - reach[m][OPPOSITE[s]] >= 4
    vshift = {n: int(room(n, "N", spacing[n[1]]) and rng.random() < shift_prob / 2)
              for n, s in sorted(nodes.items()) if "N" in s}
    hshift = {n: int(room(n, "E", spacing[n[0]]) and rng.random() < shift_prob / 2)
              for n, s in sorted(nodes.items()) if "E" in s}
    pad = 4
    cell_of = {}
    for (i, j) in sorted(nodes):
        col = int(xs[i]) + sum(vshift.get((i, jj), 0) for jj in range(j))
        row = int(ys[j]) - sum(hshift.get((ii, j), 0) for ii in range(i))
        cell_of[(i, j)] = (col + pad, row + pad + bc)
    b = _Builder()
    for n, sides in sorted(nodes.items()):
        _node_tile(b, cell_of[n], sides, stubs.get(n), turns.get(n))
    for n, sides in sorted(nodes.items()):
        for s in sorted(sides & {"E", "N"}):
            m = (n[0] + (s == "E"), n[1] + (s == "N"))
            shifted = (vshift if s == "N" else hshift).get(n, 0)
            _segment(b, rng, cell_of[n], cell_of[m], s, reach[n][s], reach[m][OPPOSITE[s]], shifted)
    for n, side in sorted(stubs.items()):
        _stub_road(b, rng, cell_of[n], side)
    return _map_dict(rng, b, name or f"procedural-{seed}", sign_prob, distractors_per_cell)


def _choose_stubs(rng: np.random.Generator, nodes: dict, prob: float) -> dict[tuple[int, int], str]:
    """Corner nodes that become T-junctions with a dead-end arm (continuing one of its roads)."""
    out = {}
    for n, sides in sorted(nodes.items()):
        if len(sides) == 2 and OPPOSITE[min(sides)] not in sides and rng.random() < prob:
            out[n] = OPPOSITE[sorted(sides)[int(rng.integers(2))]]
    return out


def _segment(b: _Builder, rng, a: tuple[int, int], z: tuple[int, int], side: str, reach_a: int,
             reach_z: int, shifted: int) -> None:
    """Straight cells (and a lane shift) from node cell a to node cell z going `side`."""
    step = SIDES[side]
    across = (1, 0) if side == "N" else (0, -1)  # where a shift moves the road
    along = (z[1] - a[1]) if side == "N" else (z[0] - a[0])
    lo, hi = 1 + reach_a, along - 1 - reach_z  # cells along the segment left for plain road
    at = int(rng.integers(lo, hi)) if shifted else None  # the generator only shifts where there is room
    cur = a
    for i in range(lo, hi + 1):
        if at is not None and i in (at, at + 1):
            if i == at:
                start = (a[0] + i * step[0], a[1] + i * step[1])
                _shift_tile(b, start, side, rng)
            continue
        off = (across[0], across[1]) if at is not None and i > at + 1 else (0, 0)
        cell = (a[0] + i * step[0] + off[0], a[1] + i * step[1] + off[1])
        b.put(cell, 0, 0 if side == "N" else 90, [cell])
        cur = cell
    del cur


def _stub_road(b: _Builder, rng, node: tuple[int, int], side: str) -> None:
    """Nothing, or one straight cell, beyond a dead-end arm (VIA's editor leaves the arm alone)."""
    step = SIDES[side]
    for i in range(2, 2 + int(rng.integers(0, 2))):
        cell = (node[0] + i * step[0], node[1] + i * step[1])
        b.put(cell, 0, 0 if side in "NS" else 90, [cell])


def _map_dict(rng, b: _Builder, name: str, sign_prob: float, distractors: float) -> dict:
    cols = max(c for c, _ in b.used) + 5
    rows = max(r for _, r in b.used) + 5
    cell_datas = [{"id_inmap": r * cols + c, "tile_id": t, "rot": rot}
                  for (c, r), (t, rot) in sorted(b.tiles.items(), key=lambda kv: (kv[0][1], kv[0][0]))]
    start = _start_cell(rng, b)
    # grass or brown ground, as VIA's own maps (its third choice, no ground at all, shows a grey
    # much like the asphalt: see README, limitations)
    data = {"map_name": name, "bg_id": int(rng.integers(0, 2)), "map_size": {"x": cols, "y": rows},
            "cell_datas": cell_datas, "anchor_offset": {"x": 0.0, "y": 0.0},
            "car_pos": {"x": float(start[0]), "y": float(start[1])}}
    data["sign_obj_datas"] = _place_signs(rng, data, sign_prob)
    data["signlane_distractors"] = []  # filled in world metres by the renderer's scene builder
    data["signlane_distractor_density"] = distractors
    return data


def _start_cell(rng: np.random.Generator, b: _Builder) -> tuple[int, int]:
    """A north-south straight with straights north of it (room to see what comes and read its
    signs: four more where there are, else two), on the network's loops (not on a dead-end stub),
    for VIA's start facing north."""
    def straight_ns(c):
        return b.tiles.get(c) == (0, 0)

    def run(c, k):
        return all(straight_ns((c[0], c[1] + i)) for i in range(-1, k + 1))
    ok = [c for c in sorted(b.tiles) if run(c, 4)] or [c for c in sorted(b.tiles) if run(c, 2)]
    north = ok or sorted(c for c in b.tiles if straight_ns(c))
    pool = north or sorted(c for c, (t, _) in b.tiles.items() if t == 0)
    return pool[int(rng.integers(len(pool)))]


def _place_signs(rng: np.random.Generator, data: dict, prob: float) -> list[dict]:
    """Signs for junction approaches (what the sign asks is always possible and never a dead
    end) and the odd stop sign on plain road."""
    from signlane.world.track import Track
    track = Track.from_via({**data, "sign_obj_datas": []})
    signs = []
    for tile in track.tiles:
        if tile.junction:
            for entry in tile.ports:
                viable = track.viable_exits(tile, entry)
                if not track.leads_on(tile, entry) or not viable or rng.random() > prob:
                    continue  # nobody arrives from a dead end
                turns = sorted({track.turn_of(entry, p) for p in viable})
                dead = sorted({track.turn_of(entry, p) for p in track.exits(tile, entry)} - set(turns))
                options = ["stop"] + turns
                options += ["no_" + t for t in ("left", "right") if t in turns and len(turns) > 1]
                options += ["no_" + t for t in dead if t in ("left", "right")]
                label = options[int(rng.integers(len(options)))]
                back, beside = float(rng.uniform(1.0, 6.0)), float(rng.uniform(1.6, 4.5))
                if _straight_before(track, tile, entry) >= back + sign_sight_m(beside):
                    _add_apart(signs, _sign_before(track, tile, entry, label, back, beside))
        elif tile.tile_id == 0 and rng.random() < 0.03:
            entry = tile.ports[int(rng.integers(2))]
            beside = float(rng.uniform(1.6, 4.5))
            if _straight_before(track, tile, entry) >= sign_sight_m(beside) and not _near_start(track, tile):
                _add_apart(signs, _sign_before(track, tile, entry, "stop", 0.0, beside))
    return signs


SIGN_APART_M = 1.5  # a sign's face is 1.25 m across: two closer than this stand in one another


def _add_apart(signs: list[dict], sign: dict) -> None:
    """Add a sign unless one already placed stands in its way (a plain road's stop sign placed
    where a junction's turn sign is: seed 17's stop stood 0.3 m behind a no_right, hidden from
    every camera)."""
    x, y = sign["pos"]["x"] * VIA_M, sign["pos"]["y"] * VIA_M
    if all(math.hypot(x - o["pos"]["x"] * VIA_M, y - o["pos"]["y"] * VIA_M) >= SIGN_APART_M for o in signs):
        signs.append(sign)


def _near_start(track, tile, cells: int = 7) -> bool:
    """Is a tile within `cells` of the start, along its column? (A car starting at rest must not
    meet a stop sign before it can see one.)"""
    c, r = track.start_cell
    return tile.col == c and -1 <= tile.row - r <= cells


def _straight_before(track, tile, entry) -> float:
    """Metres of straight road leading to a tile's open end (where a sign before it can be seen
    from far enough: a sign beside a bend is out of the camera's view until too late)."""
    metres, port = 0.0, entry
    for _ in range(20):
        nxt = track.next_tile(tile, port)
        if nxt is None or nxt[0].tile_id != 0:
            break
        tile, back_port = nxt
        metres += track.cell_m
        port = next(p for p in tile.ports if p != back_port)
    return metres


def _sign_before(track, tile, entry, label: str, back_m: float, beside_m: float) -> dict:
    """A sign on the right of traffic entering `tile` through `entry`, back_m before that edge
    and beside_m beyond the asphalt (VIA's editor puts signs 1.6-4.5 m beside it), facing it."""
    edge = (track.cell_centre(entry.cell) + 0.5 * np.array(SIDES[entry.side]) * track.cell_m) / track.cell_m * VIA_M
    travel = -np.array(SIDES[entry.side], float)
    right = np.array([travel[1], -travel[0]])
    pos = edge - travel * back_m + right * (ROAD_HALF_M + KERB_M + beside_m)
    facing = math.degrees(math.atan2(-travel[1], -travel[0]))
    return {"sign_id": SIGN_IDS[label], "pos": {"x": round(float(pos[0] / VIA_M), 4), "y": round(float(pos[1] / VIA_M), 4)},
            "rot": round((facing + 90.0) % 360.0, 3)}


__all__ = ["generate_map", "rotate_side"]
