"""Seeded procedural road networks, emitted as VIA map dicts (so one loader serves both).

A network is a coarse grid of nodes joined by straight roads; the node set comes from a random
block shape (a polyomino), some inner roads are dropped, and no node is left a dead end. Each
node becomes a tile by its degree: crossing (4), T-junction (3), straight or lane shift (2,
through), or a quarter turn of 2x2 or 4x4 cells (2, corner). Signs stand before junctions and
here and there on plain road; distractors stand along the roadside.
"""
from __future__ import annotations

import math

import numpy as np

from signlane.world.tiles import OPPOSITE, SIDES, rotate_step

TURN_ROT = {frozenset("ES"): 0, frozenset("SW"): 90, frozenset("WN"): 180, frozenset("NE"): 270}
TEE_ROT = {"W": 0, "N": 90, "E": 180, "S": 270}  # keyed by the side without road
SIGN_IDS = {"left": 0, "no_left": 1, "right": 2, "no_right": 3, "stop": 4, "straight": 5}


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
    """Node -> set of sides with a road, from block edges; inner edges dropped at random."""
    blocks = _blocks(rng, bc, br)
    edges: dict[frozenset, int] = {}  # edge -> number of blocks it borders
    for (i, j) in blocks:
        corners = [(i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)]
        for a, b in zip(corners, corners[1:] + corners[:1]):
            e = frozenset((a, b))
            edges[e] = edges.get(e, 0) + 1
    keep = set(edges)
    inner = [e for e, n in edges.items() if n == 2]
    rng.shuffle(inner)
    for e in inner:
        if rng.random() < 0.45 and _ok_without(keep, e):
            keep.discard(e)
    nodes: dict[tuple[int, int], set[str]] = {}
    for e in keep:
        a, b = sorted(e)
        side = "E" if b[0] > a[0] else "S"
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
    seen, todo = set(), [next(iter(adj))]
    while todo:
        n = todo.pop()
        if n not in seen:
            seen.add(n)
            todo += adj[n]
    return len(seen) == len(adj)


def generate_map(seed: int, name: str | None = None, size: str = "medium",
                 sign_prob: float = 0.8, distractors_per_cell: float = 0.08) -> dict:
    """A VIA map dict for a seeded random road network (plus a `signlane_distractors` key)."""
    rng = np.random.default_rng(seed)
    if size not in ("small", "medium", "large"):
        raise ValueError(f"size must be small, medium or large, not {size!r}")
    bc, br = {"small": (1, 1), "medium": (2, int(rng.integers(1, 3))), "large": (3, int(rng.integers(2, 4)))}[size]
    spacing = [int(rng.integers(7, 11)) for _ in range(max(bc, br) + 1)]
    nodes = _network(rng, bc, br)
    xs = np.concatenate([[0], np.cumsum(spacing[:bc])])
    ys = np.concatenate([[0], np.cumsum(spacing[:br])])
    pad = 2
    cols, rows = int(xs[-1]) + 1 + 2 * pad, int(ys[-1]) + 1 + 2 * pad
    cell_of = {n: (int(xs[n[0]]) + pad, int(ys[n[1]]) + pad) for n in nodes}
    tiles: dict[tuple[int, int], tuple[int, int]] = {}  # pivot cell -> (tile_id, rot)
    used: set[tuple[int, int]] = set()
    reach: dict[tuple[tuple[int, int], str], int] = {}  # cells a node tile uses along each side
    for n, sides in nodes.items():
        c = cell_of[n]
        if len(sides) == 4:
            tiles[c] = (1, 0)
        elif len(sides) == 3:
            missing = ({"N", "E", "S", "W"} - sides).pop()
            tiles[c] = (4, TEE_ROT[missing])
        elif OPPOSITE[min(sides)] in sides:
            tiles[c] = (0, 0 if "N" in sides else 90)
        else:
            k = 4 if rng.random() < 0.5 else 2
            rot = TURN_ROT[frozenset(sides)]
            du, dv = rotate_step((k // 2, k // 2), rot)
            # the block lies along both incident edges: its corner cell is the node's cell
            off = [(a, b) for a in range(k) for b in range(k)]
            su, sv = SIDES[sorted(sides)[0]], SIDES[sorted(sides)[1]]
            cells = {(c[0] + a * su[0] + b * sv[0], c[1] + a * su[1] + b * sv[1]) for a, b in off}
            tiles[(c[0] + du, c[1] + dv)] = (2 if k == 2 else 3, rot)
            used |= cells
            for s in sorted(sides):
                reach[(n, s)] = k - 1
            continue
        used.add(c)
    # plain road cells along each edge, skipping what turn blocks already cover
    for n, sides in nodes.items():
        for s in sorted(sides & {"E", "S"}):
            m = (n[0] + (s == "E"), n[1] + (s == "S"))
            a, b = cell_of[n], cell_of[m]
            step = SIDES[s]
            length = abs(b[0] - a[0]) + abs(b[1] - a[1])
            lo = 1 + reach.get((n, s), 0)
            hi = length - 1 - reach.get((m, OPPOSITE[s]), 0)
            if hi < lo - 1:
                raise AssertionError("turns overlap: spacing too small")  # spacing >= 7 prevents it
            for i in range(lo, hi + 1):
                cell = (a[0] + i * step[0], a[1] + i * step[1])
                shift = rng.random() < 0.06 and lo < i < hi
                tiles[cell] = (5 if shift else 0, 0 if s == "S" else 90)
                used.add(cell)
    cell_datas = [{"id_inmap": r * cols + c, "tile_id": t, "rot": rot}
                  for (c, r), (t, rot) in sorted(tiles.items(), key=lambda kv: (kv[0][1], kv[0][0]))]
    straight = [c for c, (t, _) in tiles.items() if t == 0]
    start = straight[int(rng.integers(len(straight)))] if straight else next(iter(tiles))
    data = {"map_name": name or f"procedural-{seed}", "bg_id": int(rng.integers(0, 4)),
            "map_size": {"x": cols, "y": rows}, "cell_datas": cell_datas,
            "anchor_offset": {"x": 0.0, "y": 0.0}, "car_pos": {"x": float(start[0]), "y": float(start[1])}}
    data["sign_obj_datas"] = _place_signs(rng, tiles, cols, rows, sign_prob)
    data["signlane_distractors"] = []  # filled in world metres by the renderer's scene builder
    data["signlane_distractor_density"] = distractors_per_cell
    return data


def _approaches(tiles: dict) -> list[tuple[tuple[int, int], str, set[str]]]:
    """(junction cell, side the car enters by, exits as turns) for every junction approach."""
    out = []
    for c, (t, rot) in tiles.items():
        if t not in (1, 4):
            continue
        sides = {"N", "E", "S", "W"} if t == 1 else {"N", "E", "S", "W"} - {
            next(k for k, v in TEE_ROT.items() if v == rot)}
        for entry in sorted(sides):  # sorted: set order of strings differs between processes
            turns = set()
            for ex in sorted(sides - {entry}):
                if ex == OPPOSITE[entry]:
                    turns.add("straight")
                else:
                    fu, fv = (-x for x in SIDES[entry])
                    eu, ev = SIDES[ex]
                    turns.add("right" if fu * ev - fv * eu > 0 else "left")
            out.append((c, entry, turns))
    return out


def _place_signs(rng: np.random.Generator, tiles: dict, cols: int, rows: int, prob: float) -> list[dict]:
    signs = []
    for c, entry, turns in _approaches(tiles):
        if rng.random() > prob:
            continue
        options = ["stop"] + sorted(turns)
        options += ["no_" + t for t in ("left", "right") if t in turns and len(turns) > 1]
        name = options[int(rng.integers(len(options)))]
        back = float(rng.uniform(0.9, 1.6))  # cells before the junction cell edge
        signs.append(_sign_at(c, entry, back, name, cols, rows))
    return signs


def _sign_at(cell: tuple[int, int], entry: str, back: float, name: str, cols: int, rows: int) -> dict:
    """A sign on the right of traffic entering `cell` through side `entry`, facing it."""
    eu, ev = SIDES[entry]  # points from the cell towards where the car comes from
    fu, fv = -eu, -ev  # travel direction
    ru, rv = -fv, fu  # right of travel, with v down the map
    lateral = 0.42  # cells right of the centreline: beyond the road edge
    u = cell[0] - cols / 2 + eu * (0.5 + back) + ru * lateral
    v = cell[1] - rows / 2 + ev * (0.5 + back) + rv * lateral
    facing_deg = math.degrees(math.atan2(eu, -ev)) % 360  # clockwise from north, towards the car
    return {"sign_id": SIGN_IDS[name], "pos": {"x": round(u, 4), "y": round(v, 4)}, "rot": round(facing_deg, 3)}
