"""Junction perception: where the road opens to the side ahead, and whether it goes on straight.

Lane markings vanish at a junction, so this looks at the road surface instead. In a bird's-eye
view of the ground ahead, a pixel is "road" when its colour is close to the asphalt just in
front of the car (the car is on the road, so that patch is a free, per-frame colour reference),
or bright paint. A side opening is a run of rows where the strip beyond the road edge on that
side is mostly road and the solid edge line of that side is missing (a side road interrupts it;
colour alone takes a grey verge, sand or dark grass for road); straight-on is road beyond the far
edge of the side road.

Ground frame: metres, x right of the car, y ahead, with the car on its lane's centre.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import cv2
import numpy as np

from signlane.camera import BirdsEye, Camera
from signlane.lanes.geometry import polyfit
from signlane.lanes.road_colour import RoadColourParams, RoadColours, check_road_colour
from signlane.lanes.road_edges import lab_box
from signlane.order_stats import median_rows


_OPEN_KERNEL = np.ones((3, 3), np.uint8)  # drops single-pixel specks of look-alike colour
_LINE_GAP_KERNEL = np.ones((5, 1), np.uint8)  # bridges gaps of a row or two in an edge line


@dataclass(frozen=True)
class Opening:
    near_m: float  # ground y where the side road begins
    far_m: float  # where it ends (or the view ends: see `closed`)
    closed: bool  # the far edge was seen
    dead: bool | None = False  # the side road visibly ends (a dead end: never an exit); None: cannot tell
    cut: bool = False  # it began before its strip came into view: the side road starts nearer than near_m
    # the ground x its near and far rows were found at (car frame): with the car askew to the road
    # (out of a bend), a side road lies at another distance along the road than ahead of the car
    x_m: float = 0.0

    @property
    def centre_m(self) -> float:
        return 0.5 * (self.near_m + self.far_m)


@dataclass(frozen=True)
class JunctionView:
    left: Opening | None
    right: Opening | None
    straight: bool | None  # road beyond the side road; None = not judged (no opening or not seen)
    road_mask: np.ndarray | None = None  # uint8 bird's-eye 0/255, for people
    straight_dead: bool | None = None  # the road ahead visibly ends past the junction; None = cannot tell


def moved_on(view: JunctionView, d_m: float) -> JunctionView:
    """A view seen d_m metres back along the road, as from here: its openings that much nearer
    (over the metre or less a car drives between two frames its heading barely turns)."""
    if d_m == 0:
        return view
    left, right = (None if o is None else replace(o, near_m=o.near_m - d_m, far_m=o.far_m - d_m)
                   for o in (view.left, view.right))
    return replace(view, left=left, right=right)


@dataclass(frozen=True)
class JunctionParams:
    x_half_m: float = 12.0
    y_range_m: tuple[float, float] = (2.0, 24.0)
    px_per_m: float = 5.0
    lane_width_m: float = 3.2
    strip_m: tuple[float, float] = (2.0, 4.5)  # side strip, metres beyond the road edge
    road_frac: float = 0.55  # a row of the strip counts as road above this fraction
    min_open_m: float = 3.5  # shortest opening (a side road is about 7 m wide)
    joined: bool = True  # an opening's rows are road from the road's edge out (see detect)
    lab_tol: tuple[float, float, float] = (28.0, 9.0, 9.0)
    shadow_floor: float = 0.35  # shadowed road keeps at least this share of the reference lightness
    edge_band_m: float = 0.7  # the edge line is looked for this far either side of where it should be
    edge_line_max_px: int = 7  # in a 320-wide image: wider bright things (sand, a grey verge) are not a line
    edge_contrast: float = 22.0  # L (0..255) a line stands above its surroundings
    # the ground far out to both sides (beyond outer_m) is mostly not road, even at a crossroads
    # (side roads fill a third of the rows at most); when more of it than this looks like road,
    # the road's colour does not set it apart from the verge (dark grass under an overcast sky)
    # and no opening can be judged. The look of the world changes slowly, so the share is
    # averaged over frames (outer_memory: weight of the past): a frame or two where the verge
    # happens to look different does not open a junction that sends the car off a bend
    outer_m: float = 8.5
    max_outer_road: float = 0.75
    outer_memory: float = 0.95
    # a road model's road is checked against the colours of this world's road and verge
    # (signlane.lanes.road_colour)
    colour: RoadColourParams = field(default_factory=RoadColourParams)


class JunctionDetector:
    """Builds its bird's-eye view once per camera; its only memory across frames is how much of
    the far ground has looked like road (see JunctionParams.outer_memory)."""

    def __init__(self, camera: Camera, params: JunctionParams | None = None):
        self.p = params or JunctionParams()
        p = self.p
        size = (int(2 * p.x_half_m * p.px_per_m), int((p.y_range_m[1] - p.y_range_m[0]) * p.px_per_m))
        self.bev: BirdsEye = camera.birdseye(size, (-p.x_half_m, p.x_half_m), p.y_range_m)
        self.visible = self.bev.seen  # (bool; made once per view)
        self._visible8 = self.bev.visible()  # (uint8 0/255, the same pixels)
        self.camera = camera
        self._bands: dict[tuple, tuple[np.ndarray, ...]] = {}  # image rows and columns of each edge band
        # visible bird's-eye pixels beyond outer_m to either side (fixed per camera)
        self._outer = self.visible.copy()
        self._outer[:, self._col(-p.outer_m):self._col(p.outer_m) + 1] = False
        self.outer_share: float | None = None  # running average of outer_road_share over frames
        self.colours = RoadColours()  # of this world's road and verge, for a road model's road
        # the car's lane up to 9 m ahead, whose colour is the road's (the near rows of a tall
        # camera's view lie 3-4 m out: the colour rules' 3 m patch shows only a corner of it)
        self._ahead = np.zeros(self.visible.shape, bool)
        self._ahead[int((p.y_range_m[1] - 9.0) * p.px_per_m):, self._col(-1.2):self._col(1.2)] = True

    def reset(self) -> None:
        """Forget the frames seen so far (a new drive, perhaps in another world)."""
        self.outer_share = None
        self.colours = RoadColours()

    def _col(self, x_m: float) -> int:
        p = self.p
        return int(np.clip((x_m + p.x_half_m) * p.px_per_m, 0, self.bev.size[0] - 1))

    def _y_of_row(self, row: np.ndarray | float) -> np.ndarray | float:
        return self.p.y_range_m[1] - (np.asarray(row) + 0.5) / self.p.px_per_m

    def road_mask(self, image_bgr: np.ndarray, maps=None) -> np.ndarray:
        """uint8 (h, w) bird's-eye mask, 255 where the ground looks like the road ahead of the car;
        with a road model's maps of the frame (seg_model.FrameMaps), where the model sees road or paint
        and the colour is not the verge's (signlane.lanes.road_colour)."""
        p = self.p
        bev = self.bev.warp(image_bgr)
        if maps is not None:
            road, paint = maps.road_in(self.bev.image_to_bev_h(), self.bev.size)
            road, self.colours = check_road_colour(road & self.visible, bev, self._ahead, self.visible, self.colours,
                                                   p.colour, keep=paint)
            return cv2.morphologyEx(road.astype(np.uint8) * 255, cv2.MORPH_OPEN, _OPEN_KERNEL)
        lab8 = cv2.cvtColor(bev, cv2.COLOR_BGR2LAB)
        y0, y1 = p.y_range_m[0], p.y_range_m[0] + 3.0
        rows = slice(int((p.y_range_m[1] - y1) * p.px_per_m), int((p.y_range_m[1] - y0) * p.px_per_m))
        cols = slice(self._col(-0.9), self._col(0.9))
        ref = median_rows(lab8[rows, cols].reshape(-1, 3))
        # each test is a box in integer Lab, so each mask is one cv2.inRange on the uint8 image:
        # road is within lab_tol of the reference (its truncated integer), or, in shadow, darker
        # but keeps its hue: any L below the reference down to shadow_floor of it
        r = [int(v) for v in ref]  # (truncated, as astype(int16) does)
        lo = [v - math.ceil(t) + 1 for v, t in zip(r, p.lab_tol)]
        hi = [v + math.ceil(t) - 1 for v, t in zip(r, p.lab_tol)]
        shade = (math.floor(p.shadow_floor * ref[0]) + 1, math.ceil(ref[0]) - 1)
        if shade[0] <= shade[1]:  # it meets the tolerance's span (it ends at the reference)
            lo[0], hi[0] = min(lo[0], shade[0]), max(hi[0], shade[1])
        road = cv2.inRange(lab8, lab_box(lo), lab_box(hi))
        # paint: lighter than the road by 25 and colourless (|a - 128| < 20)
        paint_l = math.floor(ref[0] + 25) + 1
        if paint_l <= 255:
            road = cv2.bitwise_or(road, cv2.inRange(lab8, (paint_l, 109, 0), (255, 147, 255)))
        mask = cv2.bitwise_and(road, self._visible8)
        return cv2.morphologyEx(mask, cv2.MORPH_OPEN, _OPEN_KERNEL)

    def line_response(self, image_bgr: np.ndarray, rows: tuple[int, int] | None = None) -> np.ndarray:
        """uint8 image: how far each pixel's lightness stands above the pixels around it within a
        line's width across (a horizontal top-hat): high on painted lines, low on wide bright areas.
        rows (lo, hi): only those image rows are worked out (the rest 0); the kernel is one row
        tall, so each row's response is the same as in the whole image's."""
        h = image_bgr.shape[0]
        lo, hi = rows if rows is not None else (0, h)
        lo, hi = max(lo, 0), min(hi, h)
        out = np.zeros(image_bgr.shape[:2], np.uint8)
        if hi > lo:
            grey = cv2.cvtColor(image_bgr[lo:hi], cv2.COLOR_BGR2LAB)[..., 0]  # L lifts dark roads' lines
            k = max(3, int(round(image_bgr.shape[1] / 320 * self.p.edge_line_max_px)) | 1)
            out[lo:hi] = cv2.morphologyEx(grey, cv2.MORPH_TOPHAT, np.ones((1, k), np.uint8))
        return out

    def band_rows(self, x_ms, w: int, h: int) -> tuple[int, int]:
        """The image rows (lo, hi) the edge bands along ground x = each of x_ms cross."""
        vs = [self._band(x, w, h)[1] for x in x_ms]
        vs = [v for v in vs if v.size]
        return (min(int(v.min()) for v in vs), max(int(v.max()) for v in vs) + 1) if vs else (0, 0)

    def edge_paint(self, response: np.ndarray, x_m: float) -> np.ndarray:
        """bool per bird's-eye row: a line runs along ground x = x_m (within edge_band_m) at that
        row's distance, as a solid road edge line does. Looked for in the image itself (`response`
        from line_response, over at least band_rows([x_m])), where a far line is still sharp; the
        bird's-eye view smears it."""
        h, w = response.shape[:2]
        rows, v, cols = self._band(x_m, w, h)
        out = np.zeros(self.bev.size[1], bool)
        if len(rows):
            out[rows] = response[v, cols].max(axis=1) > self.p.edge_contrast
        return out

    def _band(self, x_m: float, w: int, h: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(bird's-eye rows, their image rows (n, 1), each row's band of image columns (n, k)) of
        the edge band along ground x = x_m in a w x h image; made once per place and size."""
        p = self.p
        key = (round(x_m, 2), w, h)
        if key not in self._bands:
            y = self._y_of_row(np.arange(self.bev.size[1]))
            pts = [self.camera.ground_to_image(np.stack([np.full_like(y, x), y], 1))
                   for x in (x_m - p.edge_band_m, x_m + p.edge_band_m)]
            v = np.round(pts[0][:, 1]).astype(int)
            u0 = np.clip(np.floor(np.minimum(pts[0][:, 0], pts[1][:, 0])), 0, w).astype(int)
            u1 = np.clip(np.ceil(np.maximum(pts[0][:, 0], pts[1][:, 0])) + 1, 0, w).astype(int)
            rows = np.nonzero((v >= 0) & (v < h) & (u1 > u0))[0]
            u0, u1 = u0[rows], u1[rows]
            # each row's band as pixel indices, short bands padded by repeating their last pixel
            cols = np.minimum(u0[:, None] + np.arange(int((u1 - u0).max(initial=1))), u1[:, None] - 1)
            self._bands[key] = (rows, v[rows][:, None], cols)
        return self._bands[key]

    def outer_road_share(self, mask: np.ndarray) -> float:
        """Share of the visible bird's-eye pixels beyond outer_m to either side that look like road."""
        return float((mask[self._outer] > 0).mean()) if self._outer.any() else 0.0

    def _runs(self, frac: np.ndarray, seen: np.ndarray, paint: np.ndarray, x_m: float) -> Opening | None:
        """The nearest run of road rows (bottom = near) long enough to be a side road, along
        which the edge line (`paint`, bool per row) is missing; x_m: the strip's middle."""
        p = self.p
        n = len(frac)
        # open road beside ours looks like road and has no edge line; gaps of a row or two in a
        # line (worn paint, a speck of noise) do not open it
        paint = cv2.morphologyEx(paint.astype(np.uint8)[:, None], cv2.MORPH_CLOSE, _LINE_GAP_KERNEL).ravel() > 0
        is_road = (frac > p.road_frac) & ~paint
        row = n - 1
        while row >= 0:
            if is_road[row] and seen[row]:
                top = row
                while top - 1 >= 0 and is_road[top - 1]:
                    top -= 1
                near, far = float(self._y_of_row(row)), float(self._y_of_row(top))
                closed = top > 0 and bool(seen[top - 1])
                cut = row + 1 < n and not seen[row + 1]  # it began before the strip came into view
                if far - near >= p.min_open_m or ((cut or not closed) and far - near >= 1.5):
                    return Opening(near, far, closed, cut=cut, x_m=x_m)
                row = top - 1
            else:
                row -= 1
        return None

    def detect(self, image_bgr: np.ndarray, lane_width_m: float | None = None, maps=None) -> JunctionView:
        """Openings left and right of the ego road in an image from this detector's camera (the
        road from a road model's `maps` of it where given, else from colour)."""
        p = self.p
        lw = lane_width_m or p.lane_width_m
        mask = self.road_mask(image_bgr, maps)
        share = self.outer_road_share(mask)
        self.outer_share = share if self.outer_share is None else \
            p.outer_memory * self.outer_share + (1 - p.outer_memory) * share
        if max(share, self.outer_share) > p.max_outer_road:
            return JunctionView(None, None, None, mask)
        road_edges = (-1.5 * lw - 0.5, 0.5 * lw + 0.5)  # two-lane road, car in the right lane
        out = {}
        lines = (-1.5 * lw, 0.5 * lw)  # where each side's solid edge line runs
        # (only the rows the two edge bands cross: about half the image)
        response = self.line_response(image_bgr, self.band_rows(lines, image_bgr.shape[1], image_bgr.shape[0]))
        for side, edge, line, sgn in (("left", road_edges[0], lines[0], -1), ("right", road_edges[1], lines[1], 1)):
            a, b = sorted((edge + sgn * p.strip_m[0], edge + sgn * p.strip_m[1]))
            strip = mask[:, self._col(a):self._col(b) + 1] > 0
            seen = self.visible[:, self._col(a):self._col(b) + 1].mean(axis=1) > 0.8
            # a side road joins the road: the ground between the road's edge and the strip is
            # road on its rows too. Verge that looks like road in patches does not (random looks
            # with a road model, traced: shadowed grass read as road in blobs out in the strip,
            # the verge between them and the road's edge not, planned as a side road 20 m
            # before the junction)
            g0, g1 = sorted((edge, edge + sgn * p.strip_m[0]))
            gap = mask[:, self._col(g0):self._col(g1) + 1] > 0
            frac = np.minimum(strip.mean(axis=1), gap.mean(axis=1)) if p.joined else strip.mean(axis=1)
            out[side] = self._runs(frac, seen, self.edge_paint(response, line), 0.5 * (a + b))
        straight = None
        opening = out["right"] or out["left"]
        if opening is not None and opening.closed:
            y_a, y_b = opening.far_m + 1.0, opening.far_m + 4.0
            r0, r1 = int((p.y_range_m[1] - y_b) * p.px_per_m), int((p.y_range_m[1] - y_a) * p.px_per_m)
            if r0 >= 0:
                block = mask[r0:r1, self._col(-lw):self._col(0.0) + 1] > 0
                straight = bool(block.mean() > 0.5)
        return JunctionView(out["left"], out["right"], straight, mask)


# --- junctions of a kerbed carriageway, read from the road-edges scan ---------------------------
@dataclass(frozen=True)
class ScanJunctionParams:
    min_gap_m: float = 1.2  # a side opening: road at least this far beyond where the edge should be
    min_open_m: float = 2.5  # shortest opening (VIA's side roads are 4 m wide)
    row_gap_m: float = 0.4  # open rows this close together are one opening
    resume_m: float = 1.0  # the edge back (or the road's end) this soon after: the opening is closed
    end_seen_m: float = 1.5  # a side road is a dead end only where ground is seen this far past its end
    min_end_m: float = 2.5  # road ending nearer than this past the edge is a corner's fillet (VIA's: 1.6 m), not a
    # side road's end (VIA's shortest side road, a T's branch, ends 4 m past the edge)
    bend_look_m: float = 4.0  # ... and no road goes on within this far ahead or behind its rows there
    goes_on_m: float = 9.0  # a side road seen this far past its edge (to the view's edge) goes on (a T's arm and one tile end 8 m out)
    straight_m: float = 1.5  # road on both edges this far past a junction: it goes on straight
    in_line_m: float = 0.6  # ... with both edges this close to the lines they ran along before it
    dead_ahead_m: float = 10.0  # the road ending this soon past a junction: straight on is a dead end


def view_from_scan(scan, params: ScanJunctionParams | None = None) -> JunctionView:
    """Openings beside the carriageway and whether it goes on straight, from a RoadScan of
    signlane/lanes/road_edges.py. An opening is a run of rows where the road reaches well past
    the edge the rows before carried on (the edge 'jumped') while that edge is in view; it is
    closed when the edge comes back in line after it (a side road, not a bend: a bend moves its
    edges smoothly, or turns away for good), or, with both sides open, where the road ends just
    beyond (the far side of a T-junction reached along its stem). A side road whose end is in
    view is a dead end, as is straight on where the road visibly stops just past the junction."""
    p = params or ScanJunctionParams()
    if scan is None or len(scan.y) < 4:
        return JunctionView(None, None, None)
    found = {}
    for side, run, edge, ok, seen, sgn in (("left", scan.run_l, scan.edge_l, scan.ok_l, scan.seen_l, -1),
                                           ("right", scan.run_r, scan.edge_r, scan.ok_r, scan.seen_r, 1)):
        beyond = sgn * (run - edge)
        view = sgn * (seen - edge)  # how far past the edge the ground is in view
        open_rows = np.flatnonzero(~ok & (beyond > p.min_gap_m) & (view > 0.5))
        found[side] = _opening(scan, open_rows, beyond, view, ok, p, sgn)
    ends = scan.stop == "lost"
    if found["left"] is not None and found["right"] is not None:
        # openings on the two sides that do not overlap along the road are two junctions: keep
        # the nearer one (the far one is judged when it is next)
        (ln, lf), (rn, rf) = found["left"][:2], found["right"][:2]
        if rn > lf + p.row_gap_m:
            found["right"] = None
        elif ln > rf + p.row_gap_m:
            found["left"] = None
    both = found["left"] is not None and found["right"] is not None
    sides = {}
    for side, o in found.items():
        if o is None:
            sides[side] = None
            continue
        near, far, resumed, dead, x = o
        closed = resumed or (both and ends and scan.y[-1] - far <= p.resume_m)
        sides[side] = Opening(near, far, bool(closed), dead, x_m=x)  # dead: True / False / None (cannot tell)
    straight = dead_ahead = None
    opened = [o for o in sides.values() if o is not None]
    if opened:
        far = max(o.far_m for o in opened)
        near = min(o.near_m for o in opened)
        past = scan.y[_in_line(scan, near, far, p)]
        straight = bool(len(past) and past.max() - far >= p.straight_m)
        if straight:
            dead_ahead = _road_ends(scan, far, p)
            if dead_ahead:
                straight = False  # the road stops just past the junction: a dead end ahead
    return JunctionView(sides["left"], sides["right"], straight, straight_dead=dead_ahead)


def with_road_end(view: JunctionView, scan, params: ScanJunctionParams | None = None) -> JunctionView:
    """A painted road's junction view with the road-edge scan's word on whether the road straight
    on ends just past the junction (a dead end the edge-line detector cannot see)."""
    opened = [o for o in (view.left, view.right) if o is not None and o.closed]
    if not opened or scan is None or len(scan.y) < 4:
        return view
    dead = _road_ends(scan, max(o.far_m for o in opened), params or ScanJunctionParams())
    return replace(view, straight_dead=dead, straight=bool(view.straight) and not dead)


def _in_line(scan, near_m: float, far_m: float, p: ScanJunctionParams) -> np.ndarray:
    """Rows past a junction (y > far_m) whose two edges carry on the lines the edges ran along
    before it (their last 3 m before near_m): the road goes on straight. A bend's edges do not."""
    both = scan.ok_l & scan.ok_r
    out = both & (scan.y > far_m)
    for edge in (scan.edge_l, scan.edge_r):
        line = _line_before(scan, edge, both, near_m)
        if line is None:
            return out  # nothing to compare with: the edges being found must do
        out &= np.abs(edge - np.polyval(line, scan.y)) < p.in_line_m
    return out


def _line_before(scan, edge: np.ndarray, ok: np.ndarray, near_m: float) -> np.ndarray | None:
    """The straight line (np.polyfit coefficients) an edge ran along over its rows `ok` in the
    3 m before near_m, or None with fewer than 4 of them."""
    before = ok & (scan.y < near_m) & (scan.y > near_m - 3.0)
    return polyfit(scan.y[before], edge[before], 1) if before.sum() >= 4 else None


def _verge_colour(scan, near_m: float) -> np.ndarray | None:
    """Median Lab colour of the ground just beside the carriageway (0.4-1.4 m past its edges)
    on the rows before an opening, or None where there is not enough of it."""
    rows = np.flatnonzero(scan.ok_l & scan.ok_r & (scan.y < near_m - 0.5))
    if len(rows) < 4:
        return None
    rows = rows[:: max(1, len(rows) // 12)]
    # a box each side of each row: its pixel bounds in one step, as RoadScan.region reckons them
    x_lo = np.concatenate([scan.edge_l[rows] - 1.4, scan.edge_r[rows] + 0.4])
    x_hi = np.concatenate([scan.edge_l[rows] - 0.4, scan.edge_r[rows] + 1.4])
    y = np.concatenate([scan.y[rows], scan.y[rows]])
    u0, v1 = scan.bev.ground_to_bev(np.column_stack([x_lo, y - 0.05])).T
    u1, v0 = scan.bev.ground_to_bev(np.column_stack([x_hi, y + 0.05])).T
    h, w = scan.road.shape
    u0, u1 = np.clip(np.floor(u0), 0, w).astype(int), np.clip(np.ceil(u1), 0, w).astype(int)
    v0, v1 = np.clip(np.floor(v0), 0, h).astype(int), np.clip(np.ceil(v1), 0, h).astype(int)
    samples = [scan.lab[a:b, c:d][scan.visible[a:b, c:d]] for a, b, c, d in zip(v0, v1, u0, u1)]
    px = np.concatenate(samples) if samples else np.zeros((0, 3))
    return np.median(px, axis=0) if len(px) >= 10 else None


def _road_ends(scan, far_m: float, p: ScanJunctionParams) -> bool | None:
    """Does the road straight on end soon past a junction (ground ahead of its last row and to
    either side of it, not a bend)? None when the scan ran out of view instead."""
    if scan.stop != "lost":
        return None if scan.y[-1] - far_m < p.dead_ahead_m else False
    if scan.y[-1] - far_m >= p.dead_ahead_m:
        return False
    y_end = float(scan.y[-1])
    x_mid = float(0.5 * (scan.edge_l[-1] + scan.edge_r[-1]))
    road, vis = scan.region(x_mid - 5.0, x_mid + 5.0, y_end + 0.5, y_end + 3.5)
    k = scan.bev.px_per_m[0] * scan.bev.px_per_m[1]
    if vis.sum() < 0.5 * 30.0 * k:
        return None
    return bool(road[vis].mean() < 0.1)


def _opening(scan, rows: np.ndarray, beyond: np.ndarray, view: np.ndarray, ok: np.ndarray,
             p: ScanJunctionParams, sgn: float):
    """(near, far, resumed, dead, x) of the nearest group of open rows long enough, or None; x:
    where its rows open, just past the edge they interrupt (car frame)."""
    if len(rows) == 0:
        return None
    step = float(np.median(np.abs(np.diff(scan.y)))) if len(scan.y) > 1 else 0.125
    # the groups of rows no further apart than row_gap_m: the first long enough (or reaching the
    # scan's end) is the opening
    gaps = np.flatnonzero(np.diff(rows) * step > p.row_gap_m).tolist()
    for first, last in zip([0] + [g + 1 for g in gaps], gaps + [len(rows) - 1]):
        near, far = float(scan.y[rows[first]]), float(scan.y[rows[last]])
        if far - near >= p.min_open_m or rows[last] == len(scan.y) - 1:
            break
    else:
        return None
    group = rows[first: last + 1]
    after = np.flatnonzero(ok[group[-1] + 1:])
    resumed = bool(len(after) and scan.y[group[-1] + 1 + after[0]] - far <= p.resume_m)
    if resumed:  # and back in line with the edge before the opening: a side road, not a bend
        edge = scan.edge_r if sgn > 0 else scan.edge_l
        line = _line_before(scan, edge, ok, near)
        if line is not None:
            i = group[-1] + 1 + after[0]
            resumed = abs(float(edge[i] - np.polyval(line, scan.y[i]))) < p.in_line_m
    x = float((scan.edge_r if sgn > 0 else scan.edge_l)[group[0]]) + sgn * p.min_gap_m
    return near, far, resumed, _dead_end(scan, group, beyond, view, p, sgn), x


def _dead_end(scan, group: np.ndarray, beyond: np.ndarray, view: np.ndarray, p: ScanJunctionParams,
              sgn: float) -> bool | None:
    """Does the side road of an opening visibly end? Each of its rows is followed outwards
    (`_row_reach`): past what stands in the way (a barrier hides the near part of a side road) to
    where the verge's own ground begins. True when rows see the road end with verge beyond and no
    road goes on from there ahead of or behind the side road's rows (a bend just past the
    junction would); False when rows see it go on for `goes_on_m` or to the view's edge; None when
    too little of it is in view to tell. A row whose road ends within `min_end_m` of the edge has
    met the corner's fillet beside the side road, not the side road's end, and tells nothing."""
    if scan.road is None or scan.lab is None:
        return None
    near = float(scan.y[group[0]])
    verge = _verge_colour(scan, near)
    if verge is None:
        return None
    edge = (scan.edge_r if sgn > 0 else scan.edge_l)[group]
    h, w = scan.road.shape
    uv = np.rint(scan.bev.ground_to_bev(np.column_stack([edge, scan.y[group]]))).astype(int)  # each row's edge pixel
    ends, on, goes_on = [], 0, 0
    for kind, reach in _row_reaches(scan, np.clip(uv[:, 0], 0, w - 1), np.clip(uv[:, 1], 0, h - 1), sgn, verge, p):
        if kind == "end" and reach >= p.min_end_m:
            ends.append(reach)
        elif kind == "on":
            on += 1
            goes_on += reach >= p.goes_on_m
    if goes_on >= max(3, len(ends)):
        return False
    # fewer ends than rows running to the view's edge: the ends are the side road's far side seen
    # askew (the car still turning out of a bend), not its end. And a barrier beside the road
    # may hide all but the far rows of a short side road: three rows that see its end will do
    if len(ends) < 3 or on >= len(ends):
        return None
    x_end = float(np.median(edge)) + sgn * float(np.max(ends))
    far = float(scan.y[group[-1]])
    # around the end, ahead of and behind the side road's rows: no road carrying on. Ahead (a
    # bend onwards) must be in view; behind (a road bending back towards the car) lies outside
    # the view's wedge when the end is far out, and is judged only where it is seen
    k = scan.bev.px_per_m[0] * scan.bev.px_per_m[1]
    for y0, y1, needed in ((far + 0.6, far + p.bend_look_m, True), (near - p.bend_look_m, near - 0.6, False)):
        road, vis = scan.region(x_end - sgn * 2.0, x_end + sgn * 2.0, y0, y1)
        if vis.sum() < 0.5 * 4.0 * (y1 - y0) * k:
            if needed:
                return None  # not enough of it in view to tell a dead end from a bend
            continue
        if road[vis].mean() > 0.1:
            return False
    return True


VERGE_LAB = np.array([30.0, 12.0, 12.0])  # a verge pixel: this close to the verge's Lab colour, each channel


def _row_reaches(scan, us: np.ndarray, vs: np.ndarray, sgn: float, verge: np.ndarray, p: ScanJunctionParams):
    """How far the road of each bird's-eye row vs[i] goes past its edge at column us[i] (metres),
    outwards to side sgn: ("end", m) where the verge's own ground follows it for `end_seen_m`;
    ("on", m) where road runs to the view's edge (within 0.5 m of the last ground seen);
    ("unknown", 0) otherwise. Things that are neither road nor verge (a barrier, its shadow) are
    looked past, not taken for the end. All rows at once: row j of each array is the j-th pixel
    outwards from the edge."""
    w = scan.road.shape[1]
    k = scan.bev.px_per_m[0]
    n = max(2, int(round(p.end_seen_m * k)))
    cols = us.astype(int)[:, None] + (1 if sgn > 0 else -1) * np.arange(w)[None, :]
    inside = (cols >= 0) & (cols < w)
    cols = np.clip(cols, 0, w - 1)
    rows = vs.astype(int)
    # the verge's colour tested on the rows' own pixels before they are taken outwards from the
    # edge (the same pixels, 2-D gathers): |x - verge| < t for integer x is one integer range
    near = cv2.inRange(np.ascontiguousarray(scan.lab[rows]), tuple(np.floor(verge - VERGE_LAB) + 1),
                       tuple(np.ceil(verge + VERGE_LAB) - 1))
    road = np.take_along_axis(scan.road[rows], cols, 1) & inside
    vis = np.take_along_axis(scan.visible[rows], cols, 1) & inside
    verge_px = vis & ~road & (np.take_along_axis(near, cols, 1) > 0)
    # the first stretch of n verge pixels in a row starts where the road has ended
    runs = np.zeros((len(cols), w + 1), np.int32)
    np.cumsum(verge_px, axis=1, out=runs[:, 1:])
    full = (runs[:, n:] - runs[:, :-n]) == n
    road_vis = road & vis
    # per row, at once: the last pixel seen, where the first verge stretch starts, the last road
    # pixel before it, and the last road pixel of all (argmax finds the first True)
    last_seen = w - 1 - np.argmax(vis[:, ::-1], axis=1)
    has_start = full.any(axis=1)
    before = road_vis & (np.arange(w)[None, :] < np.argmax(full, axis=1)[:, None])
    last_before = w - 1 - np.argmax(before[:, ::-1], axis=1)
    last_road = w - 1 - np.argmax(road_vis[:, ::-1], axis=1)
    out = []
    for seen, start, any_before, end, any_road, last, top in zip(
            vis.any(axis=1).tolist(), has_start.tolist(), before.any(axis=1).tolist(), last_before.tolist(),
            road_vis.any(axis=1).tolist(), last_road.tolist(), last_seen.tolist()):
        if not seen:
            out.append(("unknown", 0.0))
        elif start:
            out.append(("end", float(end + 1) / k) if any_before else ("unknown", 0.0))
        elif any_road and top - last <= 0.5 * k:
            out.append(("on", float(last) / k))
        else:
            out.append(("unknown", 0.0))
    return out
