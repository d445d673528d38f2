"""The ego lane from marking points in ground metres, shared by canny-scan and color-hough.

Marking points in ground metres, tagged with the scan row they came from, vote for smooth lines
x(y) (a small Hough over offset, slope and bend, then least squares); the ego lane is the pair
of lines around the car a lane width apart, or two lane widths when the centre line is missing
and the road's far edge is the nearest paint on the left; a lone line gets the width prior.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from signlane.lanes.geometry import DEFAULT_LANE_WIDTH_M, Boundary, fit_boundary, shifted


@dataclass
class LaneWidthState:
    """Tracking state of the methods using this back-end: the lane width measured so far
    (metres, smoothed)."""

    lane_width_m: float | None = None

SLOPES = np.linspace(-0.5, 0.5, 21)  # dx/dy at the reference row: heading plus the bend so far
CURVATURES = np.linspace(-0.06, 0.06, 7)  # 1/m: radii down to ~15 m
BIN_M = 0.15
TIGHT_M = 0.08  # a point this close to its line's fit is on the line
CLUTTER_BAND_M = (0.3, 1.3)  # beside a line, where clutter is counted
MAX_SLOPE = 0.36  # |dx/dy| at the car: a boundary ~20 deg off our heading is not ours
MAX_BEND = 0.05  # |a| of x = a*y^2 + ...: radius >= 10 m
BEND_RIDGE = 60.0  # how strongly a pair's two bends are held together
QUAD_F = 6.0  # F-statistic a bend must reach to be fitted
LANE_WIDTH_RANGE = (0.72, 1.44)  # plausible lane widths / the prior (3.2 m: 2.3-4.6 m)
FAR_WIDTH_RANGE = (1.5, 2.7)  # ... and from the far road edge to the right edge line


@dataclass(frozen=True)
class Line:
    """A voted line: x(y) = polyval(coeffs, y) in ground metres, fitted to its points."""

    coeffs: np.ndarray
    y_lo: float
    y_hi: float
    votes: int  # distinct scan rows with a point close to the fit
    members: np.ndarray  # indices of its points

    def x_at(self, y):
        a, b, c = self.coeffs
        return (a * y + b) * y + c


@dataclass(frozen=True)
class EgoLane:
    """Boundaries in ground metres (None: not found); `seen` are those fitted through paint."""

    left: Boundary | None
    right: Boundary | None
    width_m: float  # between the boundaries at the car (measured, else the prior)
    measured: bool
    confidence: float
    seen: list[Boundary]


def ego_lane(pts: np.ndarray, rows: np.ndarray, n_rows: int, width_prior_m: float, gate_m: float = 0.3,
             min_votes: int = 4, half_width_m: float = 8.0) -> EgoLane:
    """The ego lane from marking points pts (N,2) ground metres found on scan rows `rows` (N,)
    int of n_rows; the car is at x=0, y=0 looking along +y."""
    none = EgoLane(None, None, width_prior_m, False, 0.0, [])
    if len(pts) < min_votes:
        return none
    lines = vote_lines(pts, rows, float(np.median(pts[:, 1])), half_width_m, gate_m, min_votes)
    pick = choose_ego(lines, pts, width_prior_m)
    left, right = _final_fits(pick, pts)
    if left is None and right is None:
        return none
    seen = [b for b in (left, right) if b is not None]
    width, measured = width_prior_m, False
    if left is not None and right is not None:
        width = float(right.x_at(0.0) - left.x_at(0.0)) / (2.0 if pick.far else 1.0)
        measured = LANE_WIDTH_RANGE[0] * width_prior_m <= width <= LANE_WIDTH_RANGE[1] * width_prior_m
    if pick.far and left is not None:
        left = shifted(left, width)  # the far edge -> the (unpainted) centre line
    return EgoLane(left, right, width, measured, _confidence(pick, n_rows), seen)


def _solve(G: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Solve the normal equations G c = r. Systems are tiny and solved thousands of times a
    second, so up to 3x3 by the adjugate in plain floats (numpy's per-call overhead dominates)."""
    k = len(r)
    if k <= 3:
        g = G.tolist()
        if k == 1:
            return np.array([r[0] / g[0][0]]) if g[0][0] else np.zeros(1)
        if k == 2:
            det = g[0][0] * g[1][1] - g[0][1] * g[1][0]
            if abs(det) > 1e-12 * (abs(g[0][0] * g[1][1]) + 1e-300):
                return np.array([g[1][1] * r[0] - g[0][1] * r[1], g[0][0] * r[1] - g[1][0] * r[0]]) / det
        else:
            inv = _inv3(g)
            if inv is not None:
                return inv @ r
    try:
        return np.linalg.solve(G, r)
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(G, r, rcond=None)[0]


def _inv3(g: list) -> np.ndarray | None:
    (a, b, c), (d, e, f), (h, i, j) = g
    co = [e * j - f * i, f * h - d * j, d * i - e * h]
    det = a * co[0] + b * co[1] + c * co[2]
    if abs(det) < 1e-12 * (abs(a * e * j) + 1e-300):
        return None
    return np.array([[co[0], c * i - b * j, b * f - c * e],
                     [co[1], a * j - c * h, c * d - a * f],
                     [co[2], b * h - a * i, a * e - b * d]]) / det


def _pick_order(n: int, span: float, rss_of) -> int:
    """Polynomial order the points support: a bend only where it explains clearly more than
    noise (an F-test on the residual sums; a free quadratic on noisy or far-only points would
    extrapolate wildly to the car)."""
    if n < 3 or span < 0.5:
        return 0
    if span < 4.0 or n < 8:
        return 1
    r1, r2 = rss_of(1), rss_of(2)
    return 2 if r1 - r2 > QUAD_F * r2 / (n - 3) else 1


def fit_poly(pts: np.ndarray, max_order: int = 2) -> tuple[np.ndarray, int]:
    """x(y) = a*y^2 + b*y + c through ground points (N,2): (coeffs [a, b, c], order used)."""
    y, x = pts[:, 1], pts[:, 0]
    A = np.column_stack([np.ones_like(y), y, y * y])
    G, r, xx = A.T @ A, A.T @ x, float(x @ x)
    sols = {}

    def rss_of(order):
        k = order + 1
        sols[order] = c = _solve(G[:k, :k], r[:k])
        return max(xx - float(c @ r[:k]), 0.0)  # residual sum of squares from the Gram terms
    order = min(max_order, _pick_order(len(y), float(np.ptp(y)) if len(y) else 0.0, rss_of))
    c = sols[order] if order in sols else _solve(G[:order + 1, :order + 1], r[:order + 1])
    return np.concatenate([np.zeros(2 - order), c[::-1]]), order


def vote_lines(pts: np.ndarray, rows: np.ndarray, y_ref: float, half_width_m: float, gate_m: float,
               min_votes: int, max_lines: int = 6) -> list[Line]:
    """Lines through ground points (N,2), strongest first; each takes its points away. Lines
    steeper or more bent than a lane we drive in are dropped with their points."""
    s_grid, k_grid = (a.ravel() for a in np.meshgrid(SLOPES, CURVATURES))
    n_bins = int(2 * half_width_m / BIN_M) + 1
    dy = pts[:, 1] - y_ref
    x_ref = pts[:, :1] - s_grid[None] * dy[:, None] - 0.5 * k_grid[None] * (dy * dy)[:, None]
    bins = np.floor((x_ref + half_width_m) / BIN_M).astype(np.int64)
    inside = (bins >= 0) & (bins < n_bins)
    flat = np.arange(len(s_grid))[None, :] * n_bins + bins
    # on a tie prefer the straighter hypothesis: a bent one can sweep through several lines
    bias = (0.1 * np.abs(k_grid) / CURVATURES[-1] + 0.05 * np.abs(s_grid) / SLOPES[-1])[:, None]
    free = np.ones(len(pts), bool)
    lines: list[Line] = []
    for _ in range(2 * max_lines):
        if len(lines) >= max_lines or free.sum() < min_votes:
            break
        acc = np.bincount(flat[inside & free[:, None]], minlength=len(s_grid) * n_bins)
        acc = acc.reshape(len(s_grid), n_bins)
        acc = acc[:, :-2] + acc[:, 1:-1] + acc[:, 2:] - bias  # tolerant to a bin either side
        h, b = np.unravel_index(int(np.argmax(acc)), acc.shape)
        if acc[h, b] < min_votes - 0.5:
            break
        guess = (b + 1.5) * BIN_M - half_width_m + s_grid[h] * dy + 0.5 * k_grid[h] * dy * dy
        members = np.flatnonzero(free & (np.abs(pts[:, 0] - guess) < gate_m))
        line = _refit(pts, rows, members, free, gate_m)
        free[members] = False
        if line is None:
            continue
        free[line.members] = False
        if line.votes >= max(min_votes, _chance_votes(pts, line)) and abs(line.coeffs[1]) <= MAX_SLOPE \
                and abs(line.coeffs[0]) <= MAX_BEND:
            lines.append(line)
    return lines


def _refit(pts: np.ndarray, rows: np.ndarray, members: np.ndarray, free: np.ndarray,
           gate_m: float) -> Line | None:
    """Least squares on a hypothesis' points, then its points re-gathered around that fit."""
    if len(members) < 2:
        return None
    a, b, c = fit_poly(pts[members], max_order=1)[0]
    y = pts[:, 1]
    near = np.flatnonzero(free & (np.abs(pts[:, 0] - ((a * y + b) * y + c)) < gate_m))
    if len(near) < 2:
        near = members
    coeffs, _ = fit_poly(pts[near])
    y = pts[near, 1]
    # only rows close to the fit vote: paint lies on a smooth curve, texture the gate happened
    # to collect scatters across it
    tight = np.abs(pts[near, 0] - ((coeffs[0] * y + coeffs[1]) * y + coeffs[2])) < TIGHT_M
    return Line(coeffs, float(y.min()), float(y.max()), len(np.unique(rows[near[tight]])), near)


def _chance_votes(pts: np.ndarray, line: Line) -> float:
    """Votes the line could get from clutter alone: the density of points in a 1 m band either
    side of its gate, over twice its tight width (the fit bends towards the points it is judged
    on), plus 3.5 sigma (it is the best of many hypotheses)."""
    d = np.abs(pts[:, 0] - line.x_at(pts[:, 1]))
    ring = int(np.count_nonzero((d > CLUTTER_BAND_M[0]) & (d < CLUTTER_BAND_M[1])))
    chance = ring * 2.0 * TIGHT_M / (CLUTTER_BAND_M[1] - CLUTTER_BAND_M[0])
    return chance + 3.5 * math.sqrt(chance)


@dataclass(frozen=True)
class PairFit:
    c_left: float  # x at y=0
    c_right: float
    slope: float  # shared dx/dy at y=0
    rms: float


def joint_fit(pl: np.ndarray, pr: np.ndarray) -> PairFit:
    """Two boundaries through left/right ground points (N,2): x = c_side + b*y + a_side*y^2 with
    a shared heading b and bends held together by a ridge (one lane's boundaries are parallel; on
    a sharp bend the inner one bends more). The better-seen side carries the other's heading."""
    y = np.concatenate([pl[:, 1], pr[:, 1]])
    x = np.concatenate([pl[:, 0], pr[:, 0]])
    side = np.concatenate([np.zeros(len(pl)), np.ones(len(pr))])
    A = np.column_stack([1 - side, side, y, y * y, (side - 0.5) * y * y])
    ridge = np.diag([0.0, 0.0, 0.0, 0.0, BEND_RIDGE ** 2])

    def solve(order, keep):
        k = 3 if order < 2 else 5
        Ak = A[keep, :k]
        c = _solve(Ak.T @ Ak + (ridge if k == 5 else 0.0), Ak.T @ x[keep])
        return c, x - A[:, :k] @ c

    everything = np.ones(len(y), bool)
    order = max(1, _pick_order(len(y), float(np.ptp(y)), lambda o: float(np.sum(solve(o, everything)[1] ** 2))))
    sol, res = solve(order, everything)
    keep = np.abs(res) < max(0.15, 2.5 * float(np.sqrt(np.mean(res ** 2))))  # drop strays once
    if keep.sum() >= 4:
        sol, res = solve(order, keep)
        res = res[keep]
    return PairFit(float(sol[0]), float(sol[1]), float(sol[2]), float(np.sqrt(np.mean(res ** 2))))


@dataclass(frozen=True)
class EgoPick:
    left: Line | None
    right: Line | None
    far: bool = False  # `left` is the far edge of a 2-lane road without a centre line
    width: float = 0.0  # metres between the two lines at y=0


def choose_ego(lines: list[Line], pts: np.ndarray, width_m: float = DEFAULT_LANE_WIDTH_M) -> EgoPick:
    """The pair of lines around the car a lane width (or, with the far edge, two) apart, the
    car near its lane's centre; failing that, the strongest line alone on its side."""
    best, best_score = EgoPick(None, None), 0.0
    by_x = sorted(lines, key=lambda q: float(q.x_at(0.5 * (q.y_lo + q.y_hi))))
    for i, a in enumerate(by_x):
        for b in by_x[i + 1:]:
            weak = min(a.votes, b.votes)
            if weak < 0.25 * max(a.votes, b.votes) or not _may_pair(a, b):
                continue  # a few texture spots do not make a partner for a strong line
            f = joint_fit(pts[a.members], pts[b.members])
            w = f.c_right - f.c_left
            if not (f.c_left < 0.3 and f.c_right > -0.3) or f.rms > 0.15 or abs(f.slope) > MAX_SLOPE:
                continue  # the car is between its lane's boundaries, which are parallel
            if LANE_WIDTH_RANGE[0] <= w / width_m <= LANE_WIDTH_RANGE[1]:
                far, score = False, a.votes + b.votes
            elif FAR_WIDTH_RANGE[0] <= w / width_m <= FAR_WIDTH_RANGE[1] and f.c_left < -0.75 * width_m \
                    and weak >= 8:  # the bolder guess needs two clear lines
                far, score = True, 0.6 * (a.votes + b.votes) - _votes_between(lines, a, b, w, pts)
            else:
                continue
            centre = f.c_right - w / 4.0 if far else 0.5 * (f.c_left + f.c_right)
            score -= 4.0 * max(0.0, abs(centre) - 1.3)
            if score > best_score:
                best, best_score = EgoPick(a, b, far, w), score
    return best if best.left is not None else _single(lines, width_m)


def _single(lines: list[Line], width_m: float) -> EgoPick:
    """The strongest line alone, on the side of the car it lies on."""
    singles = [ln for ln in lines if abs(float(ln.x_at(0.0))) < 7.5]
    if not singles:
        return EgoPick(None, None)
    ln = max(singles, key=lambda q: q.votes)
    x0 = float(ln.x_at(0.0))
    if x0 >= 0:  # nothing is painted right of the right edge line
        return EgoPick(None, ln) if x0 < 1.05 * width_m else EgoPick(None, None)
    # a lone left line nearer two lane widths than one is the far edge (we drive on the right)
    return EgoPick(ln, None, x0 < -width_m)


def _may_pair(a: Line, b: Line) -> bool:
    """Cheap test on the lines' own fits before the joint fit: one or two lanes apart around the car."""
    y = 0.5 * (max(a.y_lo, b.y_lo) + min(a.y_hi, b.y_hi))
    w = float(b.x_at(y) - a.x_at(y))
    return 1.8 <= w <= 9.5 and float(a.x_at(0.0)) < 2.0 and float(b.x_at(0.0)) > -2.0


def _votes_between(lines: list[Line], a: Line, b: Line, w: float, pts: np.ndarray) -> float:
    """Votes of lines midway between a and b: a centre line there says a-b is not one lane."""
    total = 0.0
    for ln in lines:
        if ln is not a and ln is not b:
            d = float(np.median(pts[ln.members, 0] - a.x_at(pts[ln.members, 1])))
            total += ln.votes if 0.3 * w < d < 0.7 * w else 0.0
    return total


def _final_fits(pick: EgoPick, pts: np.ndarray) -> tuple[Boundary | None, Boundary | None]:
    """Boundaries through the picked lines' points; a pair as parallel curves (the right points
    moved left by the width join the left ones; the right boundary is that fit moved back), so
    the heading and bend come from both lines and neither extrapolates on its own."""
    if pick.left is not None and pick.right is not None:
        merged = np.concatenate([pts[pick.left.members], pts[pick.right.members] - [pick.width, 0.0]])
        left = _fit_clean(merged)
        return left, (shifted(left, pick.width) if left is not None else None)
    if pick.left is None and pick.right is None:
        return None, None
    fit = _fit_clean(pts[(pick.left or pick.right).members])
    return (fit, None) if pick.left is not None else (None, fit)


def _fit_clean(pts: np.ndarray) -> Boundary | None:
    """fit_boundary at the order the points support, refitted twice without the strays (beyond
    3 robust sigmas of the residuals: a dash's cut end near the car would tilt the whole line)."""
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    fit = None
    for _ in range(3):
        order = fit_poly(pts)[1] if len(pts) >= 3 else 1
        new = fit_boundary(pts, order=order)
        if new is None:
            break
        fit = new
        res = np.abs(pts[:, 0] - fit.x_at(pts[:, 1]))
        keep = res < max(TIGHT_M, 3.0 * 1.4826 * float(np.median(res)))
        if keep.all():
            break
        pts = pts[keep]
    return fit


def _confidence(pick: EgoPick, n_rows: int) -> float:
    """Mean over both sides of the share of scan rows with paint on the side's line (a third
    counts as full: dashes); an inferred side adds nothing, the far-edge stand-in half."""
    def cover(line):
        return 0.0 if line is None else min(1.0, line.votes / (0.35 * n_rows))
    return float(np.clip(0.5 * (cover(pick.left) * (0.5 if pick.far else 1.0) + cover(pick.right)), 0.0, 1.0))
