"""Colour-mask sign proposals: red/blue HSV masks -> blobs -> scored, padded boxes.

Two variants share one code path, chosen by :class:`ProposalParams`:

* ``ProposalParams.published()`` is S1 step 5 exactly: one union mask (red or blue), 4-connected
  components, keep boxes with w, h >= 20 px, w, h <= 0.8 of the frame and aspect within 2:1.
* ``ProposalParams()`` (the default, "robust") keeps red and blue apart (a red ring next to a blue
  disc must not merge), blurs away sensor noise and fills holes by taking each blob's outer
  contour (a ring, or a stop sign whose white text splits the red, gives ONE box). It starts at
  a pale saturation level (faded signs) and searches a blob that does not look like a sign again
  at higher levels inside its own box (a vivid sign glued to a pale sky or wall of its colour
  separates there). Ring signs get two more chances: as a pale round hole in a red wall, and
  after a closing that joins a thin ring's broken arcs. Thresholds relax on dark and washed-out
  frames, dull tints (S * V small: bluish asphalt) are ignored, the minimum size scales with the
  frame, blobs are scored by shape (signs are discs and octagons; a blob cut by the frame edge by
  a circle fit), and non-maximum suppression and a per-frame cap finish the list. It runs coarse
  to fine (``regions``): the same search on a half-size copy, with looser size, shape and
  saturation floors, says where signs of each colour may be, and each colour's full-resolution
  search runs in windows around its own places only (``signs/roi.py``); a sign both find has the
  same box.

All images are ``uint8`` ``(H, W, 3)`` **BGR** (OpenCV order); boxes are ``(x, y, w, h)`` int
image pixels, origin top-left. OpenCV's 8-bit hue runs 0..180 (degrees / 2).
"""
from __future__ import annotations

import heapq
from dataclasses import dataclass, replace
from functools import lru_cache

import cv2
import numpy as np

from signlane.order_stats import median, sorted_median, sorted_quantile
from signlane.signs import planes
from signlane.signs import roi as sign_roi
from signlane.types import SignDetection

HueRange = tuple[int, int]
ColorSpec = tuple[str, tuple[HueRange, ...], int, int]  # colour, hue ranges, first S level, V minimum
COARSE_MIN_SCORE = 0.5  # of min_score, for the half-size pass of the region search ...
COARSE_SIZE = 0.75  # ... of min_size_frac ...
COARSE_S = 0.6  # ... and of the first saturation level
COARSE_BIG = 32  # px at half size (a 64 px sign): a coarse blob this big needs the full min_score
SPARSE = 4  # the frame-level percentiles look at every 4th row and column of the half-size copy
RING_GROW = 0.09  # a ring's width / its outer diameter, typical: the interior grows by this per side
SEARCH_LEVELS = 64  # a guard on the work of one colour's search of one window (_search): at most
SEARCH_CONTOURS = 20000  # this many levels, or until this many contours have been found
RING_HOLES = 128  # a red blob with more holes than this is textured or noisy ground, not a wall around a ring sign
TEXTURE_HOLES = 32  # a red blob with more holes than this is textured (a wall around a ring sign has a few) ...
TEXTURE_JUMP = 0.75  # ... and is searched again above this share of its pixels' saturations


@dataclass(frozen=True)
class ProposalParams:
    """Thresholds and filters; defaults are the robust variant, see :meth:`published`."""

    red_hue: tuple[HueRange, ...] = ((0, 12), (165, 180))
    red_s_min: int = 40  # first (palest) saturation level
    red_v_min: int = 45
    blue_hue: tuple[HueRange, ...] = ((88, 128),)  # sign blues; wider takes in teal crowns, purple walls
    blue_s_min: int = 40
    blue_v_min: int = 35
    s_step: int = 25  # a blob that does not look like a sign is searched again at S + s_step ...
    max_depth: int = 6  # ... inside its own box, up to this many times (0 = one level, as S1)
    confident: float = 0.9  # a blob scoring this well is not searched further
    ring_holes: bool = True  # also look for no_left/no_right rings as pale holes in red blobs
    ring_close_px: int = 7  # an extra red pass closing gaps this wide (thin, faded, broken rings)
    separate_colors: bool = True  # False = S1: one union mask, connected components, no holes filled
    connectivity: int = 4  # of S1's connected components (the robust path uses outer contours)
    close_px: int = 0  # closing kernel at 480 rows (scaled with the frame) of the main search; off,
    # because it bridges the thin white rim that parts a blue disc or a stop sign from a wall
    adaptive: bool = True  # relax V thresholds on dark frames and S on washed-out ones ...
    washed_s: float = 100.0  # ... whose 95th-percentile saturation is below this
    chroma_min: int = 18  # S * V / 255 (= max - min of B, G, R) floor: tinted dark asphalt is no sign
    blur_px: int = 3  # Gaussian pre-blur kernel (0 = none)
    min_size: int = 20  # px; w and h of a kept box must both reach it ...
    min_size_frac: float = 16 / 480  # ... or this fraction of the frame height, whichever is smaller
    max_frac: float = 0.8  # w <= max_frac * W and h <= max_frac * H
    max_aspect: float = 2.0  # long side / short side
    border_aspect: float = 4.0  # the same for a blob cut by the frame edge (a truncated sign)
    min_score: float = 0.4  # drop blobs that look like neither a disc nor an octagon
    nms_iou: float = 0.4  # 0 = no NMS
    max_proposals: int = 8  # 0 = no cap
    pad_frac: float = 0.03  # grow each box by this fraction of its size on every side
    shape_score: bool = True  # False: every proposal scores 1.0
    regions: bool = True  # coarse to fine: full resolution only around what a half-size pass finds; False: everywhere

    @classmethod
    def published(cls) -> "ProposalParams":
        """S1 step 5 exactly (red S>=70, V>=50; blue H 100-140, S>=150; union mask; 4-conn.)."""
        return cls(red_hue=((0, 10), (170, 180)), red_s_min=70, red_v_min=50, blue_hue=((100, 140),),
                   blue_s_min=150, blue_v_min=0, max_depth=0, ring_holes=False, ring_close_px=0,
                   separate_colors=False, connectivity=4, close_px=0, adaptive=False, blur_px=0,
                   min_size=20, min_size_frac=0.0,
                   max_frac=0.8, max_aspect=2.0, border_aspect=2.0, min_score=0.0, nms_iou=0.0,
                   max_proposals=0, pad_frac=0.0, shape_score=False, regions=False)


def _hue_mask(hsv: np.ndarray, hues: tuple[HueRange, ...], s_min: int, v_min: int) -> np.ndarray:
    mask = None
    for lo, hi in hues:
        m = cv2.inRange(hsv, (lo, s_min, v_min), (hi, 255, 255))
        mask = m if mask is None else cv2.bitwise_or(mask, m)
    return mask


def _scales(img: np.ndarray, params: ProposalParams, small_hsv: np.ndarray | None = None,
            sparse_hsv: np.ndarray | None = None) -> tuple[float, float]:
    """(S, V) threshold factors <= 1 from sparse percentiles of the frame: a dark frame lowers
    V minimums, a washed-out one (over-exposure, glare, haze: little saturation anywhere) lowers
    the first S level. Percentiles, so that one bright sky or one vivid wall does not decide.
    They are read off the half-size copy's HSV (`small_hsv`, made from img when not given),
    which the region search has anyway: its 2x2 averages smooth noise as the full frame's blur
    does, and every search variant then adapts to the same numbers. `sparse_hsv`: that sample
    (every SPARSE-th row and column of the half-size copy, in HSV) when the caller has only it."""
    if not params.adaptive or img.size == 0:
        return 1.0, 1.0
    if sparse_hsv is None:
        if small_hsv is None:
            small_hsv = cv2.cvtColor(_half(img), cv2.COLOR_BGR2HSV)
        sparse_hsv = small_hsv[::SPARSE, ::SPARSE]
    sparse = sparse_hsv.reshape(-1, 3)
    s95, v90 = planes.percentile_u8(sparse[:, 1], 95), planes.percentile_u8(sparse[:, 2], 90)
    return float(np.clip(s95 / params.washed_s, 0.5, 1.0)), float(np.clip(v90 / 200.0, 0.35, 1.0))


def _half(img: np.ndarray) -> np.ndarray:
    """The frame at (W // 2, H // 2) (at least 1 px), area-averaged: the region search's copy."""
    H, W = img.shape[:2]
    return cv2.resize(img, (max(1, W // 2), max(1, H // 2)), interpolation=cv2.INTER_AREA)


def _color_specs(params: ProposalParams, scales: tuple[float, float]) -> tuple[ColorSpec, ColorSpec]:
    """Red's and blue's thresholds, adapted to the frame by its `scales` (_scales)."""
    ks, kv = scales
    return (("red", params.red_hue, int(params.red_s_min * ks), int(params.red_v_min * kv)),
            ("blue", params.blue_hue, int(params.blue_s_min * ks), int(params.blue_v_min * kv)))


def color_masks(image_bgr: np.ndarray, params: ProposalParams | None = None) -> dict[str, np.ndarray]:
    """uint8 0/255 ``(H, W)`` masks of a uint8 ``(H, W, 3)`` BGR image at the first (palest)
    saturation level: keys ``red``, ``blue`` and ``union``. For display and debugging."""
    params = params or ProposalParams()
    img = _as_bgr(image_bgr)
    if img.size == 0:
        return {k: np.zeros(img.shape[:2], np.uint8) for k in ("red", "blue", "union")}
    hsv = _hsv(img, params)
    out = {c: _hue_mask(hsv, hues, s, v) for c, hues, s, v in _color_specs(params, _scales(img, params))}
    out["union"] = cv2.bitwise_or(out["red"], out["blue"])
    return out


def _hsv(img: np.ndarray, params: ProposalParams) -> np.ndarray:
    if params.blur_px > 1:  # sensor noise and JPEG blocks otherwise speckle the pale levels
        img = cv2.GaussianBlur(img, (params.blur_px | 1, params.blur_px | 1), 0)
    return cv2.cvtColor(img, cv2.COLOR_BGR2HSV)


def _as_bgr(image: np.ndarray) -> np.ndarray:
    if not isinstance(image, np.ndarray) or image.dtype != np.uint8:
        raise ValueError(f"propose: expected a uint8 numpy image, got {getattr(image, 'dtype', type(image))}")
    if image.ndim == 2:
        return np.repeat(image[:, :, None], 3, axis=2)  # cvtColor refuses an empty image
    if image.ndim != 3 or image.shape[2] not in (3, 4):
        raise ValueError(f"propose: expected an (H, W, 3) BGR image, got shape {image.shape}")
    return np.ascontiguousarray(image[:, :, :3]) if image.shape[2] == 4 else image


@dataclass(frozen=True)
class _Blob:
    box: tuple[int, int, int, int]
    color: str
    score: float


def _shape_score(contour: np.ndarray, w: int, h: int, frame_wh: tuple[int, int] | None = None) -> float:
    """0..1: how much a filled outer contour looks like a disc or an octagon.

    The outline is judged by the convex hull, so an arrow, a ring's gap or a small sign's STOP
    (which can cut the red in two) does not spoil it: aspect (signs face the road, so they are
    near-square), hull circularity 4*pi*A/P^2 (disc 1, octagon 0.95, square 0.79, triangle 0.6)
    and hull extent = hull area / box area (disc 0.785, octagon 0.83, rectangle 1, triangle 0.5).
    Solidity = area / hull area counts too, but leniently. A blob cut by the frame edge
    (`frame_wh` given) is scored by a circle fit, or by the same cues less aspect, whichever is
    better (a sign seen from the side is an ellipse), capped at 0.7: half a disc says less.
    """
    hull = cv2.convexHull(contour)
    hull_area = cv2.contourArea(hull)
    if hull_area <= 0:
        return 0.0
    solidity = cv2.contourArea(contour) / hull_area
    perim = cv2.arcLength(hull, True)
    circ = 4.0 * np.pi * hull_area / max(perim * perim, 1e-6)
    outline = _unit((circ - 0.7) / 0.2) * (1.0 - _unit(abs(hull_area / float(w * h) - 0.8) / 0.4))
    outline *= _unit((solidity - 0.3) / 0.5)
    if frame_wh is not None:
        return max(_cut_circle_score(hull, w, h, frame_wh), 0.7 * outline ** (1 / 3))
    return (outline * _unit((min(w, h) / max(w, h) - 0.35) / 0.5)) ** 0.25


def _unit(x: float) -> float:
    """x clamped to [0, 1] (np.clip costs microseconds a scalar)."""
    return min(1.0, max(0.0, float(x)))


def _cut_circle_score(hull: np.ndarray, w: int, h: int, frame_wh: tuple[int, int]) -> float:
    """Score of a blob cut by the frame edge: a least-squares circle through its hull points off
    the edge must fit them closely and be about as big as the visible part suggests."""
    W, H = frame_wh
    pts = hull.reshape(-1, 2).astype(np.float64)
    on_edge = (pts[:, 0] <= 0) | (pts[:, 1] <= 0) | (pts[:, 0] >= W - 1) | (pts[:, 1] >= H - 1)
    pts = pts[~on_edge]
    if len(pts) < 5:
        return 0.0
    a = np.column_stack([2 * pts, np.ones(len(pts))])
    (cx, cy, c), *_ = np.linalg.lstsq(a, (pts ** 2).sum(axis=1), rcond=None)
    r = float(np.sqrt(max(c + cx * cx + cy * cy, 0.0)))
    if r < 2:
        return 0.0
    resid = median(np.abs(np.hypot(pts[:, 0] - cx, pts[:, 1] - cy) - r)) / r
    size = _unit(1.0 - abs(2 * r / max(w, h) - 1.0) / 0.6) if 2 * r > max(w, h) else 1.0
    return 0.7 * _unit(1.0 - resid / 0.12) * size


@dataclass(frozen=True)
class _Ctx:
    """Per-frame constants of the blob search."""

    params: ProposalParams
    W: int
    H: int
    min_size: int
    kernel: np.ndarray | None  # closing kernel, None = no closing
    ring_kernel: np.ndarray | None  # the wider one of the extra red pass
    v_scale: float = 1.0  # the frame's V threshold factor (_scales), for the chroma floor


def _make_ctx(W: int, H: int, params: ProposalParams, v_scale: float) -> _Ctx:
    min_size = params.min_size
    if params.min_size_frac > 0:  # scale with the frame, but never ask for more than min_size
        min_size = max(4, min(params.min_size, int(round(params.min_size_frac * H))))
    return _Ctx(params, W, H, min_size, _disc(params.close_px, H), _disc(params.ring_close_px, H), v_scale)


def _chroma_floor(ctx: _Ctx) -> float:
    """S * V / 255 (= max - min of B, G, R) a pixel needs: tinted dark asphalt has little."""
    return ctx.params.chroma_min * ctx.v_scale


def _disc(px_at_480: int, H: int) -> np.ndarray | None:
    k = int(round(px_at_480 * H / 480)) if px_at_480 > 0 else 0
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k)) if k > 1 else None


def _size_ok(x: int, y: int, w: int, h: int, ctx: _Ctx) -> bool:
    p = ctx.params
    if w < ctx.min_size or h < ctx.min_size or w > p.max_frac * ctx.W or h > p.max_frac * ctx.H:
        return False
    border = x <= 0 or y <= 0 or x + w >= ctx.W or y + h >= ctx.H
    return max(w, h) <= (p.border_aspect if border else p.max_aspect) * min(w, h)


def _components(mask: np.ndarray, color: str, ctx: _Ctx) -> list[_Blob]:
    """S1's blobs: connected components of the mask, boxes straight from the stats."""
    n, _, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=ctx.params.connectivity)
    boxes = [tuple(int(v) for v in st[:4]) for st in stats[1:n]]
    return [_Blob(b, color, 1.0) for b in boxes if _size_ok(*b, ctx)]


def _search(win: planes.Window, s_min: int, roi: tuple[int, int, int, int], color: str, ctx: _Ctx,
            out: list[_Blob], window: tuple[int, int, int, int] | None = None) -> None:
    """Outer contours (holes filled) of the window's `color` pixels at saturation >= s_min inside
    roi (x0, y0, x1, y1). With `window` (a region searched alone, not the frame), a blob touching
    its inner edges may be cut by it: it is no proposal, but it is searched inside as any other.

    A blob that is not a confident sign is searched again inside its own box one saturation step
    up: a sign glued to a paler background of its colour (sky behind a blue disc, a red wall
    behind a ring) separates from it at some level, while a lone faded sign is found at the first.
    Textured or noisy ground of the colour (red soil, bricks, a red road under sensor noise) breaks
    into many pieces at every level, and the search of such frames cost up to 160 ms. So a level
    that holds the same pixels as the last is skipped, a box is searched once per level, and the
    boxes are searched largest first (a sign parting from its background is a large piece), under
    a guard of SEARCH_LEVELS levels and SEARCH_CONTOURS contours (it stopped 1% of the searches
    of `signlane eval proposals`' frames and 3% of the hard set's, and neither recall changed).
    """
    p = ctx.params
    todo = [(0, 0, s_min, roi, 0)]  # (-area, order, S level, box, depth): a heap, largest box first
    queued = {(s_min, roi)}
    order = 0
    work = SEARCH_CONTOURS
    for _ in range(SEARCH_LEVELS):
        if not todo or work <= 0:
            break
        _, _, level, box, depth = heapq.heappop(todo)
        found, deepers = _search_level(win, level, box, color, ctx, out, window)
        work -= found
        for deeper, least in deepers:
            # the levels up to the least saturation in the box hold the same pixels: the first
            # that differs is searched (uniformly saturated ground repeated one mask 4 times); a
            # blob the same at several levels of its parent's box comes back from each: once is enough
            steps = (least - level) // p.s_step + 1
            nxt = level + steps * p.s_step
            if depth + steps <= p.max_depth and nxt <= 255 and (nxt, deeper) not in queued:
                queued.add((nxt, deeper))
                order += 1
                area = (deeper[2] - deeper[0]) * (deeper[3] - deeper[1])
                heapq.heappush(todo, (-area, order, nxt, deeper, depth + steps))


def _search_level(win: planes.Window, s_min: int, roi: tuple[int, int, int, int], color: str, ctx: _Ctx,
                  out: list[_Blob], window: tuple[int, int, int, int] | None) -> tuple[int, list[tuple[tuple, int]]]:
    """One saturation level of _search inside roi: its blobs that look like signs go to `out`;
    returns the number of contours found and, for the blobs that are not confident signs, their
    box (x0, y0, x1, y1) and the least saturation of this level's pixels inside it."""
    p = ctx.params
    sat = win.crop(win.sat[color], roi)
    mask = planes.level_mask(sat, s_min, ctx.kernel)
    rings = p.ring_holes and color == "red"
    mode = cv2.RETR_CCOMP if rings else cv2.RETR_EXTERNAL
    contours, hier = cv2.findContours(mask, mode, cv2.CHAIN_APPROX_SIMPLE, offset=roi[:2])
    deeper = []
    if not contours:
        return 0, deeper
    parents = hier[0, :, 3]
    if rings:
        # holes per blob: a wall with a ring sign has a few; textured or noisy ground of the colour
        # (red soil, a red road under sensor noise) has thousands, and walking them all cost tens
        # of ms a frame
        holes = np.bincount(parents[parents >= 0], minlength=len(contours))
    for i in np.flatnonzero(parents < 0).tolist():  # holes are looked at through their blob below
        c = contours[i]
        if len(c) < 4:  # a speck
            continue
        x, y, w, h = cv2.boundingRect(c)
        if w < ctx.min_size or h < ctx.min_size:
            continue
        score = 0.0
        if _size_ok(x, y, w, h, ctx) and not _cut(x, y, w, h, window, ctx):
            border = x <= 0 or y <= 0 or x + w >= ctx.W or y + h >= ctx.H
            score = _shape_score(c, w, h, (ctx.W, ctx.H) if border else None) if p.shape_score else 1.0
            if score >= p.min_score:
                out.append(_Blob((x, y, w, h), color, score))
        if rings and 0 < holes[i] <= RING_HOLES:  # even a confident blob: a ring glued to a wall can make a round-ish whole
            out += _rings_in_holes(contours, hier[0], i, ctx, win)
        # a box that can hold no smaller blob of the least size (one that loses more than a pixel
        # each way) is not searched again: a level up only trims the same blob's fringe. Grass
        # and soil texture gives the half-size pass about 13 such boxes a frame on VIA's ground
        if score < p.confident and min(w, h) >= ctx.min_size + 2:
            lx, ly = x - roi[0], y - roi[1]
            box_sat, box_mask = sat[ly:ly + h, lx:lx + w], mask[ly:ly + h, lx:lx + w]
            if rings and holes[i] > TEXTURE_HOLES:
                # textured ground of the colour (brown soil, VIA's brown ground): one step up splits
                # it into hundreds of pieces, each searched again, level after level (10-40 ms a
                # frame). A sign in it is more saturated than nearly all of it, so the next level
                # is the first above most of its pixels
                least = _saturation_quantile(box_sat, box_mask, TEXTURE_JUMP)
            else:
                least = cv2.minMaxLoc(box_sat, box_mask)[0]
            deeper.append(((x, y, x + w, y + h), int(least)))
    return len(contours), deeper


def _saturation_quantile(sat: np.ndarray, mask: np.ndarray, q: float) -> int:
    """The saturation below which a share q of the masked pixels lie (uint8 planes, one histogram)."""
    hist = cv2.calcHist([sat], [0], mask, [256], [0, 256]).ravel()
    cum = np.cumsum(hist)
    return int(np.searchsorted(cum, q * cum[-1]))


def _cut(x: int, y: int, w: int, h: int, window: tuple[int, int, int, int] | None, ctx: _Ctx) -> bool:
    """Does box (x, y, w, h) touch an edge of `window` that is not the frame's edge?"""
    if window is None:
        return False
    x0, y0, x1, y1 = window
    return (0 < x0 >= x) or (0 < y0 >= y) or (ctx.W > x1 <= x + w) or (ctx.H > y1 <= y + h)


def _closed_rings(win: planes.Window, s_min: int, ctx: _Ctx, roi: tuple[int, int, int, int]) -> list[_Blob]:
    """Thin, faded rings break into arcs that no level joins. A wide closing joins them; a blob
    then counts only if it encloses a hole nearly its own size (the ring's interior), so that
    the wide closing does not add merged clutter. Scored a little below the plain search."""
    mask = planes.level_mask(win.crop(win.sat["red"], roi), s_min, ctx.ring_kernel)
    contours, hier = cv2.findContours(mask, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_SIMPLE, offset=roi[:2])
    out = []
    for i, c in enumerate(contours):
        parent = hier[0, i, 3]
        if parent < 0 or len(c) < 4:  # walk the holes; their parent is the ring
            continue
        _, _, hw, hh = cv2.boundingRect(c)
        x, y, w, h = cv2.boundingRect(contours[parent])
        if hw >= 0.5 * w and hh >= 0.5 * h and _size_ok(x, y, w, h, ctx) and not _cut(x, y, w, h, roi, ctx):
            score = 0.9 * _shape_score(contours[parent], w, h)
            if score >= ctx.params.min_score:
                out.append(_Blob((x, y, w, h), "red", score))
    return out


def _rings_in_holes(contours, hier: np.ndarray, parent: int, ctx: _Ctx, win: planes.Window) -> list[_Blob]:
    """Ring signs glued to a red background: their pale interior is a hole of the red blob, cut in
    two by the slash. Overlapping holes are joined; a round cluster, pale but holding a dark arrow
    (which tells it from the white text of a stop sign), gives the sign's box: the interior grown
    by a typical ring width."""
    holes = []
    j = hier[parent, 2]
    while j >= 0:
        if len(contours[j]) >= 4:  # specks are no ring interiors
            b = cv2.boundingRect(contours[j])
            if min(b[2], b[3]) >= 0.5 * ctx.min_size:
                holes.append((j, b))
        j = hier[j, 0]
    out = []
    for members in _overlapping_groups(holes):
        pts = np.concatenate([contours[k] for k in members])
        x, y, w, h = cv2.boundingRect(pts)
        score = 0.9 * _shape_score(cv2.convexHull(pts), w, h)
        if score < ctx.params.min_score or not _ring_interior(contours, members, (x, y, w, h), win):
            continue
        gx, gy = int(round(w * RING_GROW)), int(round(h * RING_GROW))
        box = (x - gx, y - gy, w + 2 * gx, h + 2 * gy)
        if _size_ok(*box, ctx):
            out.append(_Blob(box, "red", score))
    return out


def _overlapping_groups(holes: list[tuple[int, tuple[int, int, int, int]]]) -> list[list[int]]:
    """Contour indices grouped by overlapping boxes (greedy, largest first)."""
    groups: list[tuple[list[int], list[int]]] = []  # (members, [x0, y0, x1, y1])
    for j, (x, y, w, h) in sorted(holes, key=lambda t: -t[1][2] * t[1][3]):
        for members, g in groups:
            if x < g[2] and g[0] < x + w and y < g[3] and g[1] < y + h:
                members.append(j)
                g[:] = [min(g[0], x), min(g[1], y), max(g[2], x + w), max(g[3], y + h)]
                break
        else:
            groups.append(([j], [x, y, x + w, y + h]))
    return [m for m, _ in groups]


def _ring_interior(contours, members: list[int], box: tuple[int, int, int, int], win: planes.Window) -> bool:
    """Are the hole pixels mostly pale (low S) with a darker part (the arrow)?"""
    x, y, w, h = box
    m = np.zeros((h, w), np.uint8)
    cv2.drawContours(m, [contours[k] for k in members], -1, 255, -1, offset=(-x, -y))
    px = win.crop(win.hsv, (x, y, x + w, y + h))[m > 0]
    if len(px) < 8:
        return False
    # numpy's percentile and median from one sort each (order_stats): cluttered red frames test 100+ holes
    if median(px[:, 1]) > 60:
        return False
    v = np.sort(px[:, 2])
    return sorted_quantile(v, 0.05) <= 0.8 * sorted_median(v)


def box_iou(a: tuple[int, int, int, int], b: tuple[int, int, int, int]) -> float:
    """Intersection over union of two (x, y, w, h) boxes."""
    ix = min(a[0] + a[2], b[0] + b[2]) - max(a[0], b[0])
    iy = min(a[1] + a[3], b[1] + b[3]) - max(a[1], b[1])
    if ix <= 0 or iy <= 0:
        return 0.0
    inter = ix * iy
    return inter / float(a[2] * a[3] + b[2] * b[3] - inter)


def _nms(blobs: list[_Blob], iou: float, cap: int) -> list[_Blob]:
    """Greedy NMS by score; `iou` <= 0 keeps all, `cap` <= 0 is no cap."""
    order = sorted(blobs, key=lambda b: -b.score)
    keep: list[_Blob] = []
    for b in order:
        if iou > 0 and any(box_iou(b.box, k.box) > iou for k in keep):
            continue
        keep.append(b)
        if 0 < cap <= len(keep):
            break
    return keep


def _pad(box: tuple[int, int, int, int], frac: float, W: int, H: int) -> tuple[int, int, int, int]:
    x, y, w, h = box
    px, py = int(round(w * frac)), int(round(h * frac))
    x0, y0 = max(0, x - px), max(0, y - py)
    x1, y1 = min(W, x + w + px), min(H, y + h + py)
    return x0, y0, x1 - x0, y1 - y0


def _color_of(red: np.ndarray, blue: np.ndarray, box: tuple[int, int, int, int]) -> str:
    """Colour tag of a union-mask blob (S1 mode): the colour with more mask pixels in its box."""
    x, y, w, h = box
    n_red = cv2.countNonZero(red[y:y + h, x:x + w])
    return "blue" if cv2.countNonZero(blue[y:y + h, x:x + w]) > n_red else "red"


def propose(image_bgr: np.ndarray, params: ProposalParams | None = None, half: np.ndarray | None = None,
            rows: tuple[int, int] | None = None) -> list[SignDetection]:
    """Sign proposals in a uint8 ``(H, W, 3)`` BGR image (a 2-D grey image is accepted).
    `half`: the image already scaled to (W // 2, H // 2) with INTER_AREA, if the caller has it
    (the driver's lane copy): the region search then need not make it.
    `rows`: (top, bottom) image rows where signs can be (a driving camera's band around the
    horizon, signs/face_rows.py); the region search (the robust default) then looks for where
    signs may be in those rows only, and a blob they cut is no candidate. The frame's thresholds
    still come from the whole frame, so a sign inside the rows gets the same box as without them.

    Returns :class:`SignDetection`\\ s with label ``"unknown"``, ``color`` ``"red"`` or ``"blue"``,
    ``score`` in [0, 1] (shape confidence; 1.0 when shape scoring is off) and ``box`` (x, y, w, h)
    int pixels, padded by ``params.pad_frac`` and clipped to the frame, best score first.
    """
    params = params or ProposalParams()
    img = _as_bgr(image_bgr)
    H, W = img.shape[:2]
    if H == 0 or W == 0:
        return []
    if params.separate_colors and params.regions:
        blobs = _search_regions(img, params, half if half is not None and half.shape == (H // 2, W // 2, 3) else None,
                                rows)
    elif params.separate_colors:
        scales = _scales(img, params)
        blobs = _search_frame(_hsv(img, params), params, scales, _color_specs(params, scales))
    else:  # S1: one union mask, colour decided afterwards
        hsv = _hsv(img, params)
        scales = _scales(img, params)
        ctx = _make_ctx(W, H, params, scales[1])
        specs = _color_specs(params, scales)
        blobs = []
        masks = {c: _hue_mask(hsv, hues, s, v) for c, hues, s, v in specs}
        union = cv2.bitwise_or(masks["red"], masks["blue"])
        if ctx.kernel is not None:
            union = cv2.morphologyEx(union, cv2.MORPH_CLOSE, ctx.kernel)
        for b in _components(union, "", ctx):
            blobs.append(replace(b, color=_color_of(masks["red"], masks["blue"], b.box)))
    return _detections(blobs, params, W, H)


def _detections(blobs: list[_Blob], params: ProposalParams, W: int, H: int) -> list[SignDetection]:
    """The blobs after non-maximum suppression and the cap, as padded proposals, best first."""
    kept = _nms(blobs, params.nms_iou, params.max_proposals)
    return [SignDetection("unknown", round(b.score, 4), _pad(b.box, params.pad_frac, W, H), b.color) for b in kept]


def _search_frame(hsv: np.ndarray, params: ProposalParams, scales: tuple[float, float], specs,
                  frame_h: int = 0, top: int = 0) -> list[_Blob]:
    """The robust search of both colours (specs) in the whole HSV frame, or in the band of its
    rows from `top` that `hsv` holds of a frame frame_h rows high. A blob the band cuts is no
    candidate, as one a window cuts (a tall wall or tree cut to a sign-sized piece was one), but
    is searched inside as any other."""
    h, W = hsv.shape[:2]
    frame_h = frame_h or h
    ctx = _make_ctx(W, frame_h, params, scales[1])
    return _search_windows([planes.window(hsv, (0, top, W, top + h), specs, _chroma_floor(ctx))], ctx, specs,
                           whole=(top, h) == (0, frame_h))


def _search_windows(wins: list[planes.Window], ctx: _Ctx, specs, whole: bool) -> list[_Blob]:
    """The robust search of the colours of specs inside each window; pixels outside every window
    are never looked at (a blob a window cuts is no proposal, unless the window is the `whole` frame)."""
    blobs: list[_Blob] = []
    for color, _, s_min, _ in specs:  # in the full-frame order: red, red rings, blue
        for win in wins:
            _search(win, s_min, win.box, color, ctx, blobs, None if whole else win.box)
        if color == "red" and ctx.ring_kernel is not None:
            for win in wins:
                blobs += _closed_rings(win, s_min, ctx, win.box)
    return blobs


@lru_cache(maxsize=8)
def _coarse_params(params: ProposalParams) -> ProposalParams:
    """The coarse pass only says where to look: it keeps smaller and less sign-like blobs than
    the full-resolution search will (a small sign's outline is ragged at half size). Cached: a
    dataclass replace costs tens of microseconds a frame."""
    return replace(params, min_score=COARSE_MIN_SCORE * params.min_score,
                   min_size_frac=COARSE_SIZE * params.min_size_frac)


def _coarse_candidates(blobs: list[_Blob], min_score: float) -> list[_Blob]:
    """The coarse blobs worth a full-resolution look. The looser score is for small blobs, whose
    outline is ragged at half size; one COARSE_BIG px or more across is outlined as well as at
    full size, so it needs the full search's score (a wide sky, wall or asphalt patch otherwise
    sent the full-resolution search over much of the frame, to no proposal)."""
    return [b for b in blobs if min(b.box[2], b.box[3]) < COARSE_BIG or b.score >= min_score]


def _search_regions(img: np.ndarray, params: ProposalParams, small: np.ndarray | None,
                    rows: tuple[int, int] | None = None) -> list[_Blob]:
    """Coarse to fine: the robust search on a half-size copy (area-averaged, which also does the
    blur's work) finds where signs may be; the full-resolution search then runs in a window
    around each (signs/roi.py makes blurred HSV for the windows only) and gives the boxes. The
    frame's thresholds come from a sparse sample of the half-size copy, for both.
    A colour is searched at full resolution only around its own coarse blobs: a blue window
    (often sky or a wall around a blue candidate) searched for red too cost time and found
    mostly clutter (a red sign there has its own coarse blob and window).
    With `rows` (see propose) the half-size search converts and searches those rows only."""
    H, W = img.shape[:2]
    small = _half(img) if small is None else small
    h = small.shape[0]
    top, bottom = (0, h) if rows is None else (max(0, rows[0] * h // H), min(h, -(-rows[1] * h // H)))
    if bottom <= top:
        return []
    if (top, bottom) == (0, h):
        band_hsv = cv2.cvtColor(small, cv2.COLOR_BGR2HSV)
        scales = _scales(img, params, band_hsv)
    else:  # the thresholds from the whole frame's sample, as without rows (HSV is per pixel)
        band_hsv = cv2.cvtColor(small[top:bottom], cv2.COLOR_BGR2HSV)
        scales = _scales(img, params, sparse_hsv=cv2.cvtColor(np.ascontiguousarray(small[::SPARSE, ::SPARSE]),
                                                                 cv2.COLOR_BGR2HSV))
    specs = _color_specs(params, scales)
    loose = _coarse_params(params)
    # the coarse pass also keeps paler blobs: averaging 2x2 pixels halves a thin ring's saturation
    # against a white face
    pale = [(c, hues, int(COARSE_S * s_min), v_min) for c, hues, s_min, v_min in specs]
    coarse = _coarse_candidates(_search_frame(band_hsv, loose, scales, pale, h, top), params.min_score)
    return _search_around(img, params, scales, [(b.box, b.color) for b in coarse], (W / small.shape[1], H / h))


def _search_around(img: np.ndarray, params: ProposalParams, scales: tuple[float, float],
                   places: list[tuple[tuple[int, int, int, int], str]], scale: tuple[float, float]) -> list[_Blob]:
    """The full-resolution search of each colour in windows around its own places ((x, y, w, h)
    boxes, `scale` times smaller than img, and their colour)."""
    if not places:
        return []
    H, W = img.shape[:2]
    ctx = _make_ctx(W, H, params, scales[1])
    blobs: list[_Blob] = []
    for spec in _color_specs(params, scales):  # each colour only around its own places
        boxes = sign_roi.windows([box for box, color in places if color == spec[0]], scale, (W, H), ctx.min_size)
        wins = [planes.window(sign_roi.blurred_hsv(img, box, params.blur_px), box, [spec], _chroma_floor(ctx))
                for box in boxes]
        blobs += _search_windows(wins, ctx, [spec], whole=False)
    return blobs


def propose_near(image_bgr: np.ndarray, near: list[SignDetection], params: ProposalParams | None = None,
                 half: np.ndarray | None = None) -> list[SignDetection]:
    """Sign proposals of a frame searched for only around `near` (the proposals of a frame just
    before, tracked: a sign moves a few pixels a frame at 30 frames/s, and the windows reach a
    third of its size beyond it): the full-resolution search of propose's region search in those
    windows, its thresholds from this frame's own sample. A sign that first comes into view is
    not found here: the caller searches the whole frame (or band) every few frames.
    `half`: as in propose. Robust params only (`regions`); the same output as propose."""
    params = params or ProposalParams()
    img = _as_bgr(image_bgr)
    H, W = img.shape[:2]
    if H == 0 or W == 0 or not near:
        return []
    if not (params.separate_colors and params.regions):
        raise ValueError("propose_near: the robust region search's params only (separate_colors, regions)")
    small = half if half is not None and half.shape == (H // 2, W // 2, 3) else _half(img)
    scales = _scales(img, params, sparse_hsv=cv2.cvtColor(np.ascontiguousarray(small[::SPARSE, ::SPARSE]),
                                                          cv2.COLOR_BGR2HSV))
    blobs = _search_around(img, params, scales, [(d.box, d.color) for d in near], (1.0, 1.0))
    return _detections(blobs, params, W, H)
