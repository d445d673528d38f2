"""`auto` (the default): follow whatever the road offers, told apart from the image itself.

Every frame `road-edges` finds the carriageway and keeps a running measure of whether a centre
line is painted along its middle. On a kerbed carriageway with no centre line (VIA's road) the
lane is the carriageway and the car keeps its middle. On a two-lane road with a centre line the
lane is the right one, from the paint (`sliding-window`), or, where the paint is not found, the
right half of the carriageway; paint whose lane does not lie in the carriageway's right half
(the oncoming lane, taken where the right edge line is worn away), or lies beyond the right
lane (the verge past the right edge line, the edge line taken for a lane's left line), is not
found. A wide road without a centre line whose lane lines divide it (a highway) is told from a
kerbed one by the paint method finding, frame after frame, a lane clearly narrower than the
carriageway: then the lane is that one. `LaneEstimate.basis` says which
("edges" or "paint"). Where one look for lane paint cannot make a kerbed road a lane road on
its frame (the running share is too low for one more sighting to lift it over the bar), the
frame's lane is the carriageway whatever the look finds, and the look is made after the frame's
answer (`LaneMethod.settle`, which the drive stack calls once the command is out; else first
thing on the next frame): the lanes are the same as with the look made at once. On a road with
a centre line the lane is the paint's wherever it is found, so with `edges_after_answer` (the
drive stack's setting) the carriageway's scan of such a frame waits for its answer in the same
way: whether the road still has a centre line, and the scan junctions read, are then those of
the frame before, and the frame shows the frame before's drivable mask. On a road without a
centre line it also makes each frame run one method, not both: whether the road reads as lanes (a
highway) is then the frames before's, so a road read as lanes is answered from the paint where it
is found (its carriageway and its look scored after the answer), and one read as kerbed from its
carriageway (the look after the answer), even where this frame's look would tip the share over
the bar: the switch comes a frame later (measured on random looks: the paint method and the
carriageway each cost about 1.5 ms at 320x240, and frames near the bar paid both).

With a road model (`model`: `--set lanes.model=FILE`, or `shipped`), the road is the model's
(one run of the network per frame) instead of colour rules: the carriageway is scanned in its
drivable area, and the centre line is looked for in its paint and in lines found by their own
contrast; every decision above, and the junctions read from the scan, are made the same way.
The lanes are still fitted to sliding-window's own paint binary (`model_paint` fits them to the
model's paint instead: on faint dashes of looks it was not trained on, the model misses paint
the contrast rules keep).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import cv2
import numpy as np

from signlane.camera import Camera
from signlane.lanes import register, seg_model
from signlane.lanes.geometry import camera_for
from signlane.lanes.road_edges import (RoadEdgesParams, RoadEdgesState, carriageway, carriageway_estimate,
                                       drivable_mask, right_half_estimate)
from signlane.lanes.sliding_window import SlidingWindowParams, SlidingWindowState, sliding_window
from signlane.onnx_model import ModelError
from signlane.types import LaneEstimate

NAME = "auto"


@dataclass(frozen=True)
class AutoParams:
    road: RoadEdgesParams = field(default_factory=RoadEdgesParams)
    paint: SlidingWindowParams = field(default_factory=SlidingWindowParams)
    # a lane bounded by paint counts on a road without a centre line when the paint method finds
    # it this confidently and it is narrower than this share of the carriageway (a kerbed road's
    # own kerbs, a carriageway apart, do not count) ...
    lane_confidence: float = 0.7
    lane_share: float = 0.88
    lane_memory: float = 0.85  # ... averaged over frames with this weight on the past ...
    # ... above this share, a lane road. Measured on 16 randomised VIA-style drives (seeds 20-35,
    # 80 frames each): the share peaked at 0.28; on the real highway video it stays at 1
    lanes_above: float = 0.7
    beside_road: float = 0.6  # ... and this share of a band beside one of its lines is road (another lane)
    settled_below: float = 0.1  # a road whose share is below this is looked at ...
    settled_every: int = 8  # ... every this many frames (a quarter second at 30 frames/s: a highway
    # is still noticed within about 2 s, and the paint method, which costs about as much as the
    # carriageway again, runs on one frame in eight, after the frame's answer: AutoState.settle)
    model: str = ""  # a road model's ONNX file (drivable + marking heads), "shipped" for signlane/models/lanes.onnx;
    # "" = colour rules (no model)
    threads: int = 1  # the road model's onnxruntime threads
    model_paint: bool = False  # lanes fitted to the model's paint (else to sliding-window's own binary)
    # on a two-lane road the paint's lane is the car's (the right one) only where its centre lies
    # right of the carriageway's middle by at least this share of the carriageway's width (the
    # right lane's centre is about a quarter of the width right of the middle: halfway there),
    # measured over keep_right_m of the carriageway from its nearest row with both edges seen,
    # that row no further than keep_right_from_m ahead; and no further right than keep_inside_share
    # (as far past the right lane's centre: a lane centred beyond that is the verge beyond the right
    # edge line, taken for a lane where the paint method mistook the edge line for the centre line)
    keep_right_share: float = 0.125
    keep_inside_share: float = 0.375
    keep_right_m: float = 5.0
    keep_right_from_m: float = 10.0
    # on a road with a centre line, the carriageway of a frame whose paint is found is scanned
    # after the frame's answer (AutoState.settle): its lane is the paint's either way; on a road
    # without one, a frame runs the method the frames before chose (lanes: the paint first; kerbed:
    # the carriageway) and the other after its answer. Only for a caller that settles after each
    # answer or reads the frame's drivable mask one frame late (the drive stack sets it); off,
    # every frame's outputs are its own (infer, eval, autolabel)
    edges_after_answer: bool = False

    @classmethod
    def published(cls) -> "AutoParams":
        return cls()


@dataclass(frozen=True)
class _Look:
    """A kerbed road's look for lane paint on a frame, put off until the frame's answer is out."""

    image_bgr: np.ndarray
    camera: Camera
    width_m: float  # the carriageway's measured width
    scan: object  # its RoadScan
    paint: SlidingWindowState | None  # the paint method's state to look with
    forgot: bool = False  # the tracks were forgotten after the frame (the paint state goes after the look)


@dataclass(frozen=True)
class _Edges:
    """A two-lane road's carriageway scan of a frame whose lane the paint gave, put off until the
    frame's answer is out (AutoParams.edges_after_answer)."""

    image_bgr: np.ndarray
    camera: Camera
    maps: seg_model.FrameMaps | None
    forgot: bool = False  # the tracks were forgotten after the frame (the scan goes after it is made)
    look: LaneEstimate | None = None  # a road read as lanes: the frame's paint, scored against the scan


@dataclass(frozen=True)
class AutoState:
    road: RoadEdgesState = field(default_factory=RoadEdgesState)
    paint: SlidingWindowState | None = None
    lanes_seen: float | None = None  # running share of frames where paint bounded a lane inside the carriageway
    since_check: int = 0  # frames since that was last looked at
    maps: seg_model.FrameMaps | None = None  # the road model's maps of the last frame (junctions read them)
    # the last frame's look for lane paint (a kerbed road) or carriageway scan (a road with a
    # centre line), when it was put off: made by settle(), which a driver calls once the frame's
    # command is out, or else first thing on the next frame
    pending: _Look | _Edges | None = None
    drivable: np.ndarray | None = None  # the last carriageway's road mask (a frame whose scan waits shows it)
    # (bird's-eye view, road mask) of the last frame's carriageway, made the frame's drivable mask
    # by settle() (edges_after_answer: the frame shows the frame before's)
    unwarp: tuple | None = None
    # edges_after_answer: the paint method's debug mask of the last frame it answered, made by
    # settle() from its state (a frame answered from the paint shows the frame before's)
    debug: np.ndarray | None = None

    @property
    def two_lane(self) -> bool:
        return self.road.two_lane

    def forget_tracks(self) -> "AutoState":
        pending = None if self.pending is None else replace(self.pending, forgot=True)
        return AutoState(self.road.forget_tracks(), None, self.lanes_seen, maps=self.maps, pending=pending,
                         drivable=self.drivable, unwarp=self.unwarp, debug=self.debug)

    def settle(self, params: "AutoParams") -> "AutoState":
        """This state with the pending work made (itself when none is pending): what the work
        would have left had it been made during its frame."""
        if self.unwarp is not None:
            return replace(self, drivable=drivable_mask(*self.unwarp), unwarp=None).settle(params)
        if self.paint is not None and self.paint.debug_later is not None:
            return replace(self, debug=self.paint.debug_later(),
                           paint=replace(self.paint, debug_later=None)).settle(params)
        work = self.pending
        if work is None:
            return self
        if isinstance(work, _Edges):
            # (the scan reads the road's width, colour and centre-paint memory, never the last scan)
            _, _, width, road, mask = carriageway(work.image_bgr, work.camera, params.road, self.road, work.maps)
            done = replace(self, road=road.forget_tracks() if work.forgot else road, pending=None, drivable=mask)
            if work.look is None:
                return done
            return replace(done, lanes_seen=_seen(work.look, params, width, road.scan, self.lanes_seen), since_check=0)
        _, paint_state, lanes_seen = _look(work.image_bgr, work.camera, params, work.paint, self.maps, work.width_m,
                                           work.scan, self.lanes_seen)
        # (a look's lane is never shown: its debug mask is not made)
        return replace(self, paint=None if work.forgot else replace(paint_state, debug_later=None),
                       lanes_seen=lanes_seen, since_check=0, pending=None)


@register(NAME, AutoParams)
def auto(image_bgr: np.ndarray, camera: Camera | None, params: AutoParams,
         state: AutoState | None) -> tuple[LaneEstimate, AutoState]:
    image_bgr = image_bgr if image_bgr.ndim == 3 else cv2.cvtColor(image_bgr, cv2.COLOR_GRAY2BGR)
    h, w = image_bgr.shape[:2]
    state = (state or AutoState()).settle(params)
    if min(h, w) < 16:
        return LaneEstimate(NAME, False, debug_mask=np.zeros((h, w), np.uint8)), state
    cam = camera_for(image_bgr, camera)
    maps = _road_maps(image_bgr, params)
    painted = None  # the paint method's (estimate, state) on this frame, once looked for
    read_as_lanes = not state.road.two_lane and state.lanes_seen is not None and state.lanes_seen > params.lanes_above
    if params.edges_after_answer and (state.road.two_lane or read_as_lanes):
        # a road with a centre line, or one the frames before read as lanes: where the paint is
        # found it is the lane, and the carriageway (whether the road still has a centre line,
        # its trace for junctions, the share of lane sightings) can wait for the answer
        painted = _paint(image_bgr, cam, params, state.paint, maps)
        est, paint_state = painted
        if est.found and (not state.road.two_lane or _keeps_right(est, state.road.scan, params)):
            return replace(est, method=NAME, basis="paint", drivable_mask=state.drivable,
                           debug_mask=_debug(est, state, params)), \
                AutoState(state.road, paint_state, state.lanes_seen, maps=maps,
                          pending=_Edges(image_bgr, cam, maps, look=None if state.road.two_lane else est),
                          drivable=state.drivable, debug=state.debug)
    # with edges_after_answer the colour rules' drivable mask (an unwarp, about 0.1 ms) is made
    # after the answer too: the frame shows the frame before's, as a frame whose scan waits does
    later = params.edges_after_answer and maps is None
    left, right, width, road_state, mask = carriageway(image_bgr, cam, params.road, state.road, maps,
                                                       unwarp=not later)
    unwarp = None
    if later:
        unwarp = (road_state.bev, road_state.scan.road) if left is not None or right is not None else None
        mask = state.drivable if unwarp is not None else None
    if not road_state.two_lane:
        # no centre line on the carriageway's middle: a kerbed road (VIA's), or a wide road whose
        # lane lines divide it into lanes (a highway), told apart by whether paint bounds a lane
        # clearly narrower than the carriageway, frame after frame
        def whole() -> LaneEstimate:
            return carriageway_estimate(NAME, cam, left, right, width, road_state, mask, (h, w))
        # once a road has long shown none, every few frames is enough to notice a change (the
        # paint method costs about as much as the carriageway again)
        if state.lanes_seen is not None and state.lanes_seen < params.settled_below \
                and state.since_check + 1 < params.settled_every:
            return whole(), AutoState(road_state, None, state.lanes_seen, state.since_check + 1, maps, drivable=mask,
                                      unwarp=unwarp)
        if state.lanes_seen is not None and painted is None and (
                _remember(state.lanes_seen, 1.0, params.lane_memory) <= params.lanes_above
                or (params.edges_after_answer and not read_as_lanes)):
            # one look cannot make it a lane road on this frame (or, edges_after_answer, the frames
            # before read it as kerbed): its lane is the carriageway whatever the look finds, so the
            # look waits until the frame's answer is out
            return whole(), AutoState(road_state, state.paint, state.lanes_seen, maps=maps,
                                      pending=_Look(image_bgr, cam, width, road_state.scan, state.paint),
                                      drivable=mask, unwarp=unwarp)
        est, paint_state, lanes_seen = _look(image_bgr, cam, params, state.paint, maps, width, road_state.scan,
                                             state.lanes_seen, painted)
        if lanes_seen > params.lanes_above:
            if est.found:
                return replace(est, method=NAME, basis="paint", drivable_mask=mask,
                               debug_mask=_debug(est, state, params)), \
                    AutoState(road_state, paint_state, lanes_seen, maps=maps, drivable=mask, unwarp=unwarp)
            return replace(est, method=NAME), AutoState(road_state, paint_state, lanes_seen, maps=maps, drivable=mask,
                                                        unwarp=unwarp)
        return whole(), AutoState(road_state, paint_state, lanes_seen, maps=maps, drivable=mask, unwarp=unwarp)
    # (looked for already when the carriageway waited for paint that was not found: the same call)
    est, paint_state = painted or _paint(image_bgr, cam, params, state.paint, maps)
    if est.found and not _keeps_right(est, road_state.scan, params):
        # the paint bounds the oncoming lane (or straddles the centre line): the right half of the
        # carriageway instead, and the paint method searches afresh on the next frame
        est, paint_state = replace(est, found=False), None
    if est.found:
        return replace(est, method=NAME, basis="paint", drivable_mask=mask, debug_mask=_debug(est, state, params)), \
            AutoState(road_state, paint_state, state.lanes_seen, maps=maps, drivable=mask, unwarp=unwarp)
    # no paint found this frame: the right half of the carriageway
    return right_half_estimate(NAME, cam, left, right, width, mask, (h, w)), \
        AutoState(road_state, paint_state, state.lanes_seen, maps=maps, drivable=mask, unwarp=unwarp)


def _debug(est: LaneEstimate, state: AutoState, params: AutoParams) -> np.ndarray | None:
    """A paint estimate's debug mask: its own, or with edges_after_answer the frame before's."""
    return state.debug if params.edges_after_answer else est.debug_mask


def _road_maps(image_bgr: np.ndarray, params: AutoParams) -> seg_model.FrameMaps | None:
    """The road model's maps of the frame, or None without a model. ModelError for a model
    without a road output (a marking-only model cannot tell road from verge)."""
    if not params.model:
        return None
    model = seg_model.load(seg_model.resolve(params.model), params.threads)
    if not model.has_drivable:
        raise ModelError(f"{model.model.path}: a lane-marking model (classes {list(model.classes)}); auto needs a "
                         f"road model, classes {list(seg_model.ROAD_CLASSES)}")
    return model.frame_maps(np.ascontiguousarray(image_bgr[:, :, :3]))


def _paint(image_bgr: np.ndarray, cam: Camera, params: AutoParams, state: SlidingWindowState | None,
           maps: seg_model.FrameMaps | None) -> tuple[LaneEstimate, SlidingWindowState]:
    """The paint method: sliding-window on the frame, or its back-end on the road model's paint.
    With edges_after_answer its debug mask is made by settle() (AutoState.debug)."""
    if maps is None or not params.model_paint:
        return sliding_window(image_bgr, cam, params.paint, state, debug_later=params.edges_after_answer)
    from signlane.lanes.segnet import paint_lane
    return paint_lane(NAME, maps, cam, params.paint, state)


def _look(image_bgr: np.ndarray, cam: Camera, params: AutoParams, paint: SlidingWindowState | None,
          maps: seg_model.FrameMaps | None, width: float, scan, lanes_seen: float | None,
          painted: tuple[LaneEstimate, SlidingWindowState] | None = None):
    """A look for lane paint dividing a kerbed carriageway: (the paint method's estimate, its new
    state, the running share of frames where it bounded a lane inside the carriageway). `painted`:
    the paint method's (estimate, state) of this frame, if it has run on it already."""
    est, paint_state = painted or _paint(image_bgr, cam, params, paint, maps)
    return est, paint_state, _seen(est, params, width, scan, lanes_seen)


def _seen(est: LaneEstimate, params: AutoParams, width: float, scan, lanes_seen: float | None) -> float:
    """The running share of lane sightings with this frame's paint estimate: did it bound a lane
    inside the carriageway (`width` m wide, `scan` its RoadScan)?"""
    inside = est.found and est.confidence >= params.lane_confidence and width > 0 \
        and est.lane_width_m < params.lane_share * width and _road_beside(est, scan, params)
    return _remember(lanes_seen, float(inside), params.lane_memory)


def _keeps_right(est: LaneEstimate, scan, params: AutoParams) -> bool:
    """Does a paint estimate's lane lie in the right half of a two-lane carriageway (`scan`, its
    RoadScan: this frame's, or with edges_after_answer the frame before's), centred near the right
    lane's centre? True where the scan cannot tell (too few near rows with both edges seen). On a
    look whose edge line is worn away, the paint method can take the far edge line and the centre
    line for the car's lane lines; out of a bend, the right edge line and the verge beyond it."""
    if scan is None or len(scan.y) == 0 or est.path_m is None or len(est.path_m) < 2:
        return True
    traced = (scan.y >= est.path_m[0, 1]) & (scan.y <= est.path_m[-1, 1])  # where the paint lane was traced
    if _beyond_right_edge(est, scan, np.flatnonzero(scan.ok_r & traced), params):
        return False
    both = np.flatnonzero(scan.ok_l & scan.ok_r)
    # (a wide road's far edge comes into view some metres ahead: the rows from there on)
    if len(both) == 0 or scan.y[both[0]] > params.keep_right_from_m:
        return True
    near = both[scan.y[both] <= scan.y[both[0]] + params.keep_right_m]
    near = near[traced[near]]
    if len(near) < params.road.min_rows:
        return True
    mid = 0.5 * (scan.run_l[near] + scan.run_r[near])
    width = float(np.median(scan.run_r[near] - scan.run_l[near]))
    if not params.road.min_width_m < width < params.road.max_width_m:
        return True
    ys = scan.y[near]
    centre = np.interp(ys, est.path_m[:, 1], est.path_m[:, 0])  # the paint lane's centre on those rows
    share = float(np.median(centre - mid)) / width
    return params.keep_right_share <= share <= params.keep_inside_share


def _beyond_right_edge(est: LaneEstimate, scan, rows: np.ndarray, params: AutoParams) -> bool:
    """Is a paint lane centred beyond the carriageway's right edge, over the nearest keep_right_m
    of the `rows` where that edge is seen? The verge beyond a right edge line, taken for a lane
    whose left line is the edge line: with the car near the right edge, the carriageway's left
    edge comes into view only far ahead, so the width's share cannot tell, but the right edge can."""
    rows = rows[scan.y[rows] <= scan.y[rows[0]] + params.keep_right_m] if len(rows) else rows
    if len(rows) < params.road.min_rows:
        return False
    centre = np.interp(scan.y[rows], est.path_m[:, 1], est.path_m[:, 0])
    return float(np.median(centre - scan.run_r[rows])) > 0.0


def road_state(state) -> RoadEdgesState | None:
    """The road-edges state inside a lane method's state (auto or road-edges), else None."""
    if isinstance(state, AutoState):
        return state.road
    return state if isinstance(state, RoadEdgesState) else None


def _remember(memory: float | None, value: float, weight: float) -> float:
    return value if memory is None else weight * memory + (1 - weight) * value


def _road_beside(est: LaneEstimate, scan, params: AutoParams) -> bool:
    """Road-coloured ground covers a band 0.5-1.5 m beyond one of the lane's lines, over the
    nearest 6 m seen: another lane there (a kerbed road's kerbs have verge beyond them)."""
    if scan is None or scan.road is None or len(scan.y) == 0:
        return False
    centre = -est.offset * est.lane_width_m
    y0 = float(scan.y[0])
    for x0, x1 in ((centre - est.lane_width_m / 2 - 1.5, centre - est.lane_width_m / 2 - 0.5),
                   (centre + est.lane_width_m / 2 + 0.5, centre + est.lane_width_m / 2 + 1.5)):
        road, seen = scan.region(x0, x1, y0, y0 + 6.0)
        if seen.sum() > 20 and (road & seen).sum() >= params.beside_road * seen.sum():
            return True
    return False
