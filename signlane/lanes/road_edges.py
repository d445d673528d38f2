"""`road-edges`: the carriageway from its surface, for roads without lane paint (VIA's one 4 m
carriageway between white kerbs), and whether a centre line is painted on it.

In a bird's-eye view of the ground ahead, a pixel is road when its colour is close to the road
just in front of the car (the car stands on the road: that patch is a free, per-frame colour
reference, as in `signlane.junction`), or bright and colourless (kerbs and paint). Row by row
from the car outwards, the run of road pixels around the last row's centre gives the two edges;
an edge that jumps away from where its last rows lead (a side road opening, a field of
road-coloured ground) is not an edge on that row, and the other edge and the measured width
stand in for it. The edges are fitted as lane boundaries (shared geometry, `lanes.geometry`), so
the lane is the whole carriageway and `offset` is from its middle.

The state carries the measured width and how much of the carriageway's middle has looked like a
painted line (averaged over frames): `centre_paint` above `paint_share` means a two-lane road.
A road that has shown its centre line stays a two-lane road while it stays two lanes wide
(`two_lanes_m`), even where the line fades from view (worn paint, shadow, glare, a look the
rules do not know): its lane is still the right half, not the whole carriageway.

Given a road model's maps of the frame (`seg_model.FrameMaps`: `--set lanes.model=FILE`), the
road and the paint are the model's, warped into the same view, instead of the colour rules:
a verge that looks like road, or a look the rules do not know, no longer decides where the
carriageway is. The model's road is checked against the colours this world's road and verge
have shown so far (`road_colour`): verge the model takes for road, where its colour is the
verge's, is not road. The scan, the fits and everything read from the scan (junctions) are the same.
"""
from __future__ import annotations

import bisect
import itertools
import math
from dataclasses import dataclass, field, replace
from functools import lru_cache

import cv2
import numpy as np

from signlane.camera import BirdsEye, Camera, row_spans
from signlane.lanes import register
from signlane.lanes.geometry import Boundary, camera_for, estimate_from_fits, fit_boundary, slant
from signlane.lanes.road_colour import RoadColourParams, RoadColours, check_road_colour
from signlane.lanes.seg_model import FrameMaps
from signlane.order_stats import median_rows
from signlane.types import LaneEstimate

NAME = "road-edges"
_OPEN = np.ones((3, 3), np.uint8)
_GREY = ((113, 113), (143, 143))  # colourless: |a|, |b| < 16 in uint8 Lab (a and b bounds)


@dataclass(frozen=True)
class RoadEdgesParams:
    x_half_m: float = 14.0  # wide enough to see a side road end (a dead end) from the junction
    depth_m: float = 19.0  # bird's-eye depth beyond the nearest visible ground (to see a road end past a junction)
    px_per_m: float = 8.0
    lab_tol: tuple[float, float, float] = (26.0, 9.0, 9.0)
    shadow_floor: float = 0.35  # shadowed road keeps at least this share of the reference lightness
    # a road model's road is checked against the colours of this world's road and verge
    # (signlane.lanes.road_colour)
    colour: RoadColourParams = field(default_factory=RoadColourParams)
    bright_l: float = 30.0  # paint: this much lighter than the road either side of it ...
    line_max_m: float = 0.6  # ... over a run narrower than this
    width_m: float = 4.0  # nominal carriageway width (VIA's); the measured one takes over
    min_width_m: float = 2.2
    max_width_m: float = 9.0  # wider rows are a junction or a bend seen side-on
    jump_m: float = 0.35  # an edge further than this from where its last rows lead ...
    step_m: float = 0.5  # ... and further than this from its last row is no edge
    fit_near_m: float = 9.0  # boundaries are fitted over their nearest this many metres
    min_rows: int = 8  # edge rows needed for a boundary
    paint_band_m: float = 0.35  # the middle band looked at for a painted centre line
    paint_share: float = 0.12  # share of middle-band rows with paint that makes a two-lane road
    paint_memory: float = 0.9  # weight of the past in the centre-paint average
    # a two-lane road stays one, its centre line seen or not, while it is at least this wide: two
    # of the narrowest lanes (2.75 m); VIA's kerbed carriageway is 4 m (3.6-4.4 in its look-alikes)
    two_lanes_m: float = 5.5
    # ... and it stops being one only once this many well-seen frames in a row (a second at 30
    # frames/s) measure it narrower: a frame's carriageway can come out narrow (random looks,
    # traced: a 7.4 m road measured 7-8 m, and 4.7-5.1 m on single frames, each of which let go
    # of the hold while its centre line faded, and the car steered to the carriageway's middle;
    # entering a bend, the road leaving the view sideways measured narrow for a third of a second)
    release_frames: int = 30
    # a carriageway narrower than this (two of the narrowest lanes) has no centre line, whatever
    # its middle shows: in a bend the middle band can run over a kerb
    # (random looks, traced: VIA's kerbed road with grey kerbs, measured 4.2-4.8 m, turned
    # "two-lane" in a right bend within a third of a second, and the paint method steered the
    # car onto the inner kerb)
    centre_line_from_m: float = 5.5

    @classmethod
    def published(cls) -> "RoadEdgesParams":
        return cls()  # no published source: the robust method is the only variant


@dataclass(frozen=True)
class RoadEdgesState:
    width_m: float | None = None
    centre_paint: float | None = None  # running share of middle rows that show a painted line
    bev: BirdsEye | None = None
    scan: "RoadScan | None" = None  # the last frame's scan (junctions are read from it)
    road_lab: tuple[float, float, float] | None = None  # the road's colour, averaged over frames
    # the road showed a centre line and has been two lanes wide (two_lanes_m) ever since
    held: bool = False
    narrow_frames: int = 0  # well-seen frames in a row, up to the last, narrower than two_lanes_m
    colours: RoadColours = RoadColours()  # of this world's road and verge, for a road model's road

    @property
    def two_lane(self) -> bool:
        return self.held or (self.centre_paint is not None and self.centre_paint > RoadEdgesParams.paint_share)

    def forget_tracks(self) -> "RoadEdgesState":
        """What outlives a break in following (a junction crossed on a planned path): the road's
        width, colour and kind, not the last frame's scan."""
        return replace(self, scan=None)


def road_edges_bev(cam: Camera, p: RoadEdgesParams, state: RoadEdgesState) -> BirdsEye:
    """The bird's-eye view the carriageway is scanned in (kept in the state while the camera is)."""
    return _bev(cam, p, state)


def _bev(cam: Camera, p: RoadEdgesParams, state: RoadEdgesState) -> BirdsEye:
    if state.bev is not None and state.bev.camera == cam:
        return state.bev
    near = cam.image_to_ground(np.array([[cam.width / 2, cam.height - 1.0]]))[0]
    y0 = float(near[1]) if np.isfinite(near[1]) else 1.0
    w = int(2 * p.x_half_m * p.px_per_m)
    h = int(p.depth_m * p.px_per_m)
    return cam.birdseye((w, h), (-p.x_half_m, p.x_half_m), (y0, y0 + p.depth_m))


def road_mask(bev_bgr: np.ndarray, visible: np.ndarray, p: RoadEdgesParams,
              known: tuple[float, float, float] | None = None):
    """(road, bright, reference Lab, Lab image) of a bird's-eye BGR image: masks of
    road-coloured and of bright-and-grey pixels. The reference is the patch just ahead of the car,
    unless that patch looks nothing like the road colour `known` from earlier frames (the car is
    over a kerb or off the road): then the known colour."""
    lab8 = cv2.cvtColor(bev_bgr, cv2.COLOR_BGR2LAB)
    lab = lab8.astype(np.int16)
    ref = _patch_ahead(lab, p)
    if known is not None and (abs(ref[0] - known[0]) > p.lab_tol[0] or np.abs(ref[1:] - known[1:]).max() > p.lab_tol[1]):
        ref = np.asarray(known)
    ref = np.round(ref).astype(np.int16)
    # every test is a box in integer Lab, so each mask is one cv2.inRange on the uint8 image:
    # road colour is within lab_tol of the reference, or (lightness) a shadow of it, darker but
    # above shadow_floor of it
    r = [int(v) for v in ref]
    lo = [math.floor(v - t) + 1 for v, t in zip(r, p.lab_tol)]
    hi = [math.ceil(v + t) - 1 for v, t in zip(r, p.lab_tol)]
    lo[0] = min(lo[0], math.floor(p.shadow_floor * r[0]) + 1)
    road = cv2.inRange(lab8, lab_box(lo), lab_box(hi))
    bright = _lines(lab8, p)
    # paint and kerbs belong to the carriageway, and so does grey asphalt lighter than the patch
    # ahead by more than the tolerance (a mottled road: else its light blotches are holes that
    # stop the scan well inside the road)
    lighter = cv2.inRange(lab8, (min(255, math.ceil(r[0] + p.lab_tol[0])),) + _GREY[0], (255,) + _GREY[1])
    # (lines too: a yellow centre line is not grey, and would split the carriageway in two)
    either = cv2.bitwise_or(cv2.bitwise_or(road, lighter), bright)
    road = cv2.morphologyEx(cv2.bitwise_and(either, visible.view(np.uint8)), cv2.MORPH_OPEN, _OPEN) > 0
    return road, (bright > 0) & visible, ref, lab


def _patch_ahead(lab: np.ndarray, p: RoadEdgesParams) -> np.ndarray:
    """Median Lab colour of the bird's-eye patch just ahead of the car."""
    h, w = lab.shape[:2]
    return median_rows(lab[h - max(2, int(1.2 * p.px_per_m)):, w // 2 - int(0.8 * p.px_per_m): w // 2 + int(0.8 * p.px_per_m)]
                       .reshape(-1, 3))


def learned_road_mask(bev_bgr: np.ndarray, visible: np.ndarray, bev: BirdsEye, maps: FrameMaps, p: RoadEdgesParams,
                      colours: RoadColours):
    """road_mask's outputs from a road model's maps instead of colour rules: (road, paint,
    the patch ahead's Lab colour, Lab image, the world's colours updated). Paint lies on the
    road, so it is road too; road whose colour is the verge's is not (road_colour)."""
    lab8 = cv2.cvtColor(bev_bgr, cv2.COLOR_BGR2LAB)
    lab = lab8.astype(np.int16)
    road, paint = maps.road_in(bev.image_to_bev_h(), bev.size)
    # paint: the model's, and lines by their own contrast (as without a model): a faint dashed
    # centre line the model misses still tells a two-lane road from a kerbed one
    paint = (paint | (_lines(lab8, p) > 0)) & visible
    road, colours = check_road_colour(road & visible, bev_bgr, _lane_ahead(road.shape, p.px_per_m), visible,
                                      colours, p.colour, keep=paint)
    road = cv2.morphologyEx((road | paint).view(np.uint8) & visible.view(np.uint8), cv2.MORPH_OPEN, _OPEN) > 0
    return road, paint, _patch_ahead(lab, p), lab, colours


@lru_cache(maxsize=4)
def _lane_ahead(shape: tuple[int, int], px_per_m: float) -> np.ndarray:
    """bool bird's-eye mask (read-only, made once per view) of the car's lane over the first 6 m
    of the view: where the road's colour is learned."""
    h, w = shape
    out = np.zeros(shape, bool)
    out[h - int(6 * px_per_m):, w // 2 - int(1.2 * px_per_m): w // 2 + int(1.2 * px_per_m)] = True
    out.setflags(write=False)
    return out


def lab_box(v) -> tuple[int, int, int]:
    """A cv2.inRange bound of integer Lab values, clipped to uint8."""
    return tuple(min(255, max(0, int(x))) for x in v)


def _lines(lab8: np.ndarray, p: RoadEdgesParams) -> np.ndarray:
    """Painted lines in a bird's-eye uint8 Lab image (uint8 0/255): pixels lighter than the ground
    either side of them by bright_l, in a run narrower than line_max_m (a top-hat across the road),
    grey or yellow. Local contrast, not lightness against the patch ahead: with that patch in
    shadow, the whole sunlit road is lighter than it, and kerbed roads read as having a centre line."""
    k = max(3, int(round(p.line_max_m * p.px_per_m)) | 1)
    ridge = cv2.morphologyEx(np.ascontiguousarray(lab8[..., 0]), cv2.MORPH_TOPHAT, np.ones((1, k), np.uint8))
    lines = cv2.compare(ridge, p.bright_l, cv2.CMP_GT)
    grey = cv2.inRange(lab8, (0,) + _GREY[0], (255,) + _GREY[1])
    yellow = cv2.inRange(lab8, (0, _GREY[0][0], 149), (255, _GREY[1][0], 255))  # b > 20
    return cv2.bitwise_and(lines, cv2.bitwise_or(grey, yellow))


@dataclass(frozen=True)
class RoadScan:
    """The row-by-row scan of a bird's-eye road mask, near to far, in ground metres (x right,
    y ahead): each row's run of road around the path (its ends), whether each end is the edge
    carried on from the rows before (ok) or has jumped away (a side road, a field of
    road-coloured ground), the edges used (measured, or the other edge and the width), how far
    the ground is visible to each side, and why the scan stopped ("lost": no road ahead of the
    path, "view": the end of the bird's-eye view)."""

    y: np.ndarray
    run_l: np.ndarray
    run_r: np.ndarray
    ok_l: np.ndarray
    ok_r: np.ndarray
    edge_l: np.ndarray
    edge_r: np.ndarray
    seen_l: np.ndarray
    seen_r: np.ndarray
    width_m: float
    stop: str
    y_view: float  # the far end of the view
    road: np.ndarray | None = None  # the bird's-eye road mask scanned (bool), for junction checks
    visible: np.ndarray | None = None  # where the bird's-eye view sees ground (bool)
    bev: BirdsEye | None = None
    lab: np.ndarray | None = None  # the bird's-eye view in Lab (int16), for colour checks

    def region(self, x0: float, x1: float, y0: float, y1: float, lab: bool = False):
        """(road, visible) bool pixels of the bird's-eye view inside ground x in [x0, x1] and
        y in [y0, y1] metres (empty arrays when outside); with lab=True also their Lab colours."""
        b = self.bev
        (u0, v1), (u1, v0) = b.ground_to_bev(np.array([[min(x0, x1), min(y0, y1)], [max(x0, x1), max(y0, y1)]]))
        h, w = self.road.shape
        # scalar arithmetic (the junction checks call this dozens of times a frame)
        u0, u1 = min(max(math.floor(u0), 0), w), min(max(math.ceil(u1), 0), w)
        v0, v1 = min(max(math.floor(v0), 0), h), min(max(math.ceil(v1), 0), h)
        if lab:
            return self.road[v0:v1, u0:u1], self.visible[v0:v1, u0:u1], self.lab[v0:v1, u0:u1]
        return self.road[v0:v1, u0:u1], self.visible[v0:v1, u0:u1]


def row_runs(mask: np.ndarray) -> tuple[list[int], list[int], list[int]]:
    """The runs of True in each row of a bool (h, w) mask: (first columns, last columns, bounds),
    row r's runs being indices bounds[r] to bounds[r + 1] - 1 of the first two, left to right.
    One pass over the mask with a column of False either side of each row, flattened: changes
    then alternate, a run's start then its end, and never cross from one row to the next."""
    h, w = mask.shape
    wide = w + 2
    pad = np.zeros((h, wide), np.bool_)
    pad[:, 1:-1] = mask
    flat = pad.ravel()
    change = np.flatnonzero(flat[1:] != flat[:-1])
    starts, ends = change[0::2] + 1, change[1::2]  # the first True of a run, the last
    rows = starts // wide
    return ((starts - rows * wide - 1).tolist(), (ends % wide - 1).tolist(),
            np.searchsorted(rows, np.arange(h + 1)).tolist())


def scan_edges(road: np.ndarray, visible: np.ndarray, bev: BirdsEye, p: RoadEdgesParams,
               width_m: float) -> RoadScan:
    """Scan a bird's-eye road mask row by row from the car outwards (see RoadScan)."""
    h, w = road.shape
    k = p.px_per_m
    centre = w / 2.0
    out: list[tuple] = []
    hist_l: list[float] = []
    hist_r: list[float] = []
    misses = blind = 0
    stop = "view"
    # every row's runs of road (first and last column, as lists) and first and last seen column,
    # in one pass each: per-row numpy calls were most of the scan's cost
    run_start, run_end, bounds = row_runs(road)
    # each row's seen span (made once per view when `visible` is the view's own): where every
    # row sees one span, whether a column is seen is a comparison with the span's ends
    any_seen, first_seen, last_seen, spans = bev.seen_rows if visible is bev.seen else row_spans(visible)
    # the loop runs once per row, so the parameters and the edge test are inlined, and each
    # edge's slant is worked out only when a row adds to its history
    jump, step_px, blind_max = p.jump_m * k, p.step_m * k, 10 * k
    min_w, max_w, near_px = p.min_width_m, p.max_width_m, int(0.6 * k)
    slant_l = slant_r = 1.0
    for row in range(h - 1, -1, -1):
        c = int(round(centre))
        lo_run, hi_run = bounds[row], bounds[row + 1]
        i = bisect.bisect_right(run_start, c, lo_run, hi_run) - 1  # the run starting at or before c
        if not (0 <= c < w) or i < lo_run or run_end[i] < c:
            line = road[row]
            lo_c = max(0, c - near_px)
            near = np.flatnonzero(line[lo_c: c + near_px + 1])
            if len(near) == 0:
                misses += 1
                if misses > 3:
                    stop = "lost"
                    break
                continue
            c = lo_c + int(near[np.argmin(np.abs(near - (c - lo_c)))])
            i = bisect.bisect_right(run_start, c, lo_run, hi_run) - 1
        misses = 0
        left, right = run_start[i], run_end[i]  # the run of road through c
        # a run that ends where the view does (the road bends out of the frame) has no edge there
        seen = any_seen[row]
        # (a seen column two beyond the run's end lies inside the frame: left > 1, right < w - 2)
        if spans:
            f_row, l_row = first_seen[row], last_seen[row]
            seen_l = seen and f_row <= left - 2 <= l_row
            seen_r = seen and f_row <= right + 2 <= l_row
        else:
            seen_l = left > 1 and bool(visible[row, left - 2])
            seen_r = right < w - 2 and bool(visible[row, right + 2])
        # an edge is where its last rows lead: near the straight continuation of its last two
        # rows, or a small step from the last (a kink of VIA's chamfered turns); a side road or
        # a bend seen side-on moves the run's end much further in one row
        ok_l = seen_l and (
            not hist_l or abs(left - (hist_l[-1] if len(hist_l) < 2 else 2 * hist_l[-1] - hist_l[-2])) <= jump
            or abs(left - hist_l[-1]) <= step_px)
        ok_r = seen_r and (
            not hist_r or abs(right - (hist_r[-1] if len(hist_r) < 2 else 2 * hist_r[-1] - hist_r[-2])) <= jump
            or abs(right - hist_r[-1]) <= step_px)
        run = (right - left) / k
        blind = 0 if (ok_l or ok_r) else blind + 1
        if blind > blind_max:
            break  # 10 m without an edge: nothing more to follow
        # a row crosses a bending road aslant: its run is the width over the cosine of the edges'
        # angle, from each edge's last 6 rows (1 when straight ahead; about 1.3 on a 6 m bend)
        if ok_l:
            hist_l.append(left)
            if len(hist_l) >= 6:
                slope = (hist_l[-1] - hist_l[-6]) / 5  # pixels across per row: rows and columns share a scale
                slant_l = slant(slope)
        if ok_r:
            hist_r.append(right)
            if len(hist_r) >= 6:
                slope = (hist_r[-1] - hist_r[-6]) / 5
                slant_r = slant(slope)
        across = run / (0.5 * (slant_l + slant_r))
        if ok_l and ok_r and min_w < across < max_w:
            width_m = 0.9 * width_m + 0.1 * across
        # where an edge jumped away, it goes on from its last rows (or one width from the other)
        if ok_l:
            lo = left
        elif ok_r:
            lo = right - width_m * k * slant_r
        else:
            lo = hist_l[-1] if hist_l else centre - width_m * k / 2
        if ok_r:
            hi = right
        elif ok_l:
            hi = left + width_m * k * slant_l
        else:
            hi = hist_r[-1] if hist_r else centre + width_m * k / 2
        centre = 0.5 * (lo + hi)
        out.append((row, left, right, ok_l, ok_r, lo, hi, first_seen[row] if seen else c, last_seen[row] if seen else c))
    a = np.fromiter(itertools.chain.from_iterable(out), float, count=9 * len(out)).reshape(-1, 9)
    x0, y1 = bev.x_range_m[0], bev.y_range_m[1]
    to_x = lambda col: x0 + (col + 0.5) / k  # noqa: E731
    return RoadScan(y1 - (a[:, 0] + 0.5) / k, to_x(a[:, 1] - 0.5), to_x(a[:, 2] + 0.5), a[:, 3] > 0, a[:, 4] > 0,
                    to_x(a[:, 5] - 0.5), to_x(a[:, 6] + 0.5), to_x(a[:, 7]), to_x(a[:, 8]), width_m, stop,
                    float(bev.y_range_m[1]), road, visible, bev)


def carriageway(image_bgr: np.ndarray, cam: Camera, p: RoadEdgesParams, state: RoadEdgesState,
                maps: FrameMaps | None = None, unwarp: bool = True):
    """(left, right Boundary | None, width m, new state, road mask uint8 in the image or None).
    With a road model's `maps` of the frame, its road and paint instead of the colour rules (the
    mask is then the model's road at the frame's size). unwarp=False: no colour-rule mask (None;
    a caller that shows it later makes it with drivable_mask)."""
    h, w = image_bgr.shape[:2]
    bev = _bev(cam, p, state)
    visible = bev.seen
    bev_bgr = bev.warp(image_bgr[:, :, :3])
    colours = state.colours  # (learned only from a road model's road)
    if maps is None:
        road, bright, ref, lab_img = road_mask(bev_bgr, visible, p, state.road_lab)
    else:
        road, bright, ref, lab_img, colours = learned_road_mask(bev_bgr, visible, bev, maps, p, colours)
    scan = replace(scan_edges(road, visible, bev, p, state.width_m or p.width_m), lab=lab_img)
    left = _fit(np.column_stack([scan.run_l, scan.y])[scan.ok_l], p)
    right = _fit(np.column_stack([scan.run_r, scan.y])[scan.ok_r], p)
    good = left is not None and right is not None and p.min_width_m < scan.width_m < p.max_width_m
    # only a well-seen carriageway says whether it has a centre line, and one narrower than two
    # lanes has none (see RoadEdgesParams.centre_line_from_m)
    paint = None if not good else (_centre_paint(bright, bev, scan, p) if scan.width_m >= p.centre_line_from_m else 0.0)
    memory, lab = state.centre_paint, state.road_lab
    if paint is not None:
        memory = paint if memory is None else p.paint_memory * memory + (1 - p.paint_memory) * paint
    held, narrow = state.held, state.narrow_frames
    if good:
        lab = tuple(float(v) for v in (ref if lab is None else 0.9 * np.asarray(lab) + 0.1 * ref))
        narrow = narrow + 1 if scan.width_m < p.two_lanes_m else 0
        two = state.two_lane or (memory is not None and memory > p.paint_share)
        held = two and (narrow == 0 or (state.held and narrow < p.release_frames))
    if maps is not None:  # the model's road, found or not
        mask = maps.frame_mask(maps.road, w, h)
    else:
        mask = drivable_mask(bev, road) if unwarp and (left is not None or right is not None) else None
    new_state = RoadEdgesState(scan.width_m, memory, bev, scan, lab, held, narrow, colours)
    return left, right, scan.width_m, new_state, mask


def drivable_mask(bev: BirdsEye, road: np.ndarray) -> np.ndarray:
    """A bird's-eye road mask (bool) as the frame's uint8 0/255 drivable mask."""
    return bev.unwarp(road.view(np.uint8) * 255, cv2.INTER_NEAREST)


def centre_path(scan: "RoadScan", smooth_rows: int = 5) -> np.ndarray | None:
    """The carriageway's middle traced by a scan, (N,2) ground metres near to far, smoothed."""
    if scan is None or len(scan.y) < smooth_rows:
        return None
    x = 0.5 * (scan.edge_l + scan.edge_r)
    k = np.ones(smooth_rows) / smooth_rows
    r = smooth_rows // 2  # (np.pad's edge mode, without its cost)
    xs = np.convolve(np.concatenate((np.full(r, x[0]), x, np.full(r, x[-1]))), k, mode="valid")[: len(x)]
    return np.column_stack([xs, scan.y])


@register(NAME, RoadEdgesParams)
def road_edges(image_bgr: np.ndarray, camera: Camera | None, params: RoadEdgesParams,
               state: RoadEdgesState | None) -> tuple[LaneEstimate, RoadEdgesState]:
    """The carriageway in a uint8 (H, W, 3) BGR frame as the lane; see the module docstring."""
    image_bgr = image_bgr if image_bgr.ndim == 3 else cv2.cvtColor(image_bgr, cv2.COLOR_GRAY2BGR)
    h, w = image_bgr.shape[:2]
    state = state or RoadEdgesState()
    if min(h, w) < 16:
        return LaneEstimate(NAME, False, debug_mask=np.zeros((h, w), np.uint8), basis="edges"), state
    cam = camera_for(image_bgr, camera)
    left, right, width, new_state, mask = carriageway(image_bgr, cam, params, state)
    return carriageway_estimate(NAME, cam, left, right, width, new_state, mask, (h, w)), new_state


def carriageway_estimate(method: str, cam: Camera, left, right, width: float, state: RoadEdgesState,
                         mask: np.ndarray | None, shape: tuple[int, int]) -> LaneEstimate:
    """The whole carriageway as the lane (from carriageway()'s outputs), with its traced middle."""
    debug = mask if mask is not None else np.zeros(shape, np.uint8)
    est = estimate_from_fits(method, cam, left, right, width, None, debug)
    path = centre_path(state.scan) if est.found else None
    return replace(est, basis="edges", path_m=path, drivable_mask=mask)


def right_half_estimate(method: str, cam: Camera, left, right, width: float, mask: np.ndarray | None,
                        shape: tuple[int, int]) -> LaneEstimate:
    """The right half of a two-lane carriageway as the lane (where its centre line's paint was
    not found this frame)."""
    mid = None if left is None or right is None else Boundary((left.coeffs + right.coeffs) / 2, left.y_range)
    debug = mask if mask is not None else np.zeros(shape, np.uint8)
    est = estimate_from_fits(method, cam, mid, right, width / 2, 0.5 if mid is not None else None, debug)
    return replace(est, basis="edges", drivable_mask=mask)


def _fit(g: np.ndarray, p: RoadEdgesParams):
    if len(g) < p.min_rows:
        return None
    g = g[g[:, 1] <= g[:, 1].min() + p.fit_near_m]  # the near part: where steering looks
    return fit_boundary(g, order=2, min_points=p.min_rows)


def _centre_paint(bright: np.ndarray, bev: BirdsEye, scan: RoadScan, p: RoadEdgesParams) -> float | None:
    """Share of rows (with both edges) whose middle band holds bright paint, or None."""
    both = scan.ok_l & scan.ok_r
    if both.sum() < p.min_rows:
        return None
    mid = 0.5 * (scan.run_l[both] + scan.run_r[both])
    uv = bev.ground_to_bev(np.column_stack([mid, scan.y[both]]))
    band = max(1, int(round(p.paint_band_m * p.px_per_m)))
    w = bright.shape[1]
    u, v = uv[:, 0].astype(int), uv[:, 1].astype(int)  # truncated, as int() does
    lo = np.clip(u - band, 0, w)
    hi = np.maximum(np.clip(u + band + 1, 0, w), lo)
    # paint in each row's band [lo, hi): a difference of the rows' running sums
    runs = np.zeros((len(v), w + 1), np.int32)
    np.cumsum(bright[v], axis=1, out=runs[:, 1:])
    rows = np.arange(len(v))
    return float(np.mean(runs[rows, hi] - runs[rows, lo] > 0))
