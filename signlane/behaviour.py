"""The sign-aware driving behaviour: a small explicit state machine over lane following.

States (the `Command.state` string):
- `cruise`: follow the lane at cruise speed, slower in curves.
- `approach`: a confirmed sign ahead: slow to the approach speed until it is dealt with.
- `stopping` / `stopped`: a stop sign: roll to a full stop before it, hold (2 s by default), go.
- `junction-left|right|straight`: markings vanish in a junction, so the car follows a planned
  path (straight on, or an arc to the chosen exit) in the odometry frame until it is through.
- `lost`: no lane and nothing planned: coast straight (to a stand, or on at `lost_speed`).

Exit choice at a junction: `left`/`right`/`straight` signs take that exit when it exists;
`no_left`/`no_right` never take that exit; with no instruction, straight if possible, else right.
Throttle is a target-speed fraction (VIA semantics): speed targets become throttle by dividing
by `max_speed`; there are no brakes, so slowing is coasting and stops are planned ahead.
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, replace

import numpy as np

from signlane.angles import wrap_pi
from signlane.control import PurePursuit, path_bend_towards, path_curvature
from signlane.junction import JunctionView, Opening
from signlane.odometry import OdoPose
from signlane.road_heading import LaneLateral, RoadHeading
from signlane.types import LaneEstimate

TURN_SIGNS = {"left", "right", "straight", "no_left", "no_right"}
BANS = {"no_left": "left", "no_right": "right"}  # the way each "no turn" sign bans


@dataclass(frozen=True)
class BehaviourParams:
    max_speed: float = 10.0  # m/s at throttle 1 (the simulator's)
    cruise_speed: float = 5.0
    approach_speed: float = 3.0
    lost_speed: float = 0.0  # m/s kept with the lane lost (0: coast to a stand); a pilot steering needs no lane
    junction_speed: float = 2.8
    lateral_accel: float = 2.0  # m/s^2 allowed in curves
    curve_preview_m: float = 12.0  # how far along the traced lane a bend slows the car
    coast_decel: float = 1.5  # m/s^2 the car slows at with throttle 0
    stop_before_m: float = 3.0  # where to stop, metres before the sign
    stop_hold_s: float = 2.0
    stop_margin_s: float = 0.5  # held a little longer than required
    wheelbase_m: float = 1.8
    camera_forward_m: float = 0.0  # the camera's ground point ahead of the rear axle; poses are the camera's
    right_radius_m: float = 5.0  # turns on a painted two-lane road (right-hand traffic)
    left_radius_m: float = 7.6
    lane_width_m: float = 3.2
    kerbed_radius_m: float = 4.6  # turns on a kerbed carriageway (the car keeps its middle): VIA's
    # car turns no tighter than 4.2 m
    # pure-pursuit lookahead (m, + m per m/s): VIA's turns are tight (6 m radius) and chamfered,
    # and a long lookahead cuts them; painted roads bend gently and their far paint is noisier
    lookahead_kerbed: tuple[float, float] = (3.5, 0.3)
    lookahead_painted: tuple[float, float] = (5.0, 0.5)
    # ... shortened on a painted road's bends so that the aim point lies at most this far to the
    # side of the car's heading (ld^2 / 2R, metres; the lane is 3.2 m wide): aimed far across a
    # bend, the car ran inside it. A kerbed carriageway's bends are tight junction-like corners
    # the short lookahead already holds
    max_cut_painted_m: float = 0.6
    commit_near_m: float = 12.0  # plan a junction once its side road starts this close ...
    commit_cut_m: float = 14.0  # ... or, where it starts before the view shows its side, once it is in view this close
    # an opening that starts before the view shows its side (cut) is a side road only once an
    # earlier frame of the last cut_seen_m driven saw an opening on that side whose far side lay
    # where this one's does (within cut_far_m): a side road's far edge is a fixed place on the
    # ground, seen on every frame as the car comes up to it. Road-coloured verge seen on one
    # frame is not (random looks, traced: a 1.6 m "opening" at the right strip's view edge, seen
    # on that frame alone, was taken for the right turn a sign asked for, 30 m before its junction)
    cut_seen_m: float = 4.0
    cut_far_m: float = 1.5
    # where the road ahead is judged a dead end (a T reached along its stem, a corner), a side
    # opening that this frame does not show is still where a frame of the last side_memory_m
    # driven saw it (closed, not cut), moved on by the metres driven since: the car has to turn
    # there, and a road model reads a side arm 10-15 m out on only some frames (random looks,
    # dev seed 100, traced: a T's right arm seen on one frame in ten, its left arm cut on
    # another; no plan was made, the car drove into the T's mouth and off the road)
    side_memory_m: float = 4.0
    # on a painted road a junction is planned with its side roads' ends where the frames of the
    # last steady_m driven saw them (their medians): one frame's reading of a far edge can be
    # metres off (Behaviour._steadied)
    steady_m: float = 4.0
    instruction_range_m: float = 40.0  # a turn sign applies to a junction within this distance after it
    sign_slack_m: float = 2.0  # a sign placed this much past a junction's far side (misjudged distance) still counts
    dead_memory_m: float = 6.0  # dead-end verdicts are forgotten this far after the last opening seen
    replan_margin_m: float = 4.0  # a plan may be made again until the car is this close to the junction
    aligned_rad: float = 0.3  # a junction is planned once the car points along its road within this ...
    commit_late_m: float = 6.0  # ... or, askew, once its side road is this close
    # a lone opening with the road ending ahead, toward which the lane already bends this sharply
    # (1/m; a 25 m circle): a bend (its outer side looks like road ending, its inner like an
    # opening), left to the lane follower. The lane at a junction runs straight up to it
    bend_not_junction: float = 0.04
    # ... or, on a painted road, bent so on a frame of the last bend_memory_m driven: a lone
    # opening with the road ending ahead is a bend when the lane showed one lately, whatever this
    # frame's lane says
    # (random looks, traced: a left bend's lane bent 0.044-0.055 1/m for a third of a second,
    # then read straight on the frames of the bend's mouth, where it was planned as a forced
    # left turn and the car left the road)
    bend_memory_m: float = 4.0
    # straight on past a lone opening on the inside of a painted bend at least this sharp (1/m; an
    # 83 m circle): keep following the lane, as on a kerbed carriageway, not a path laid straight
    # along the car. A gentle bend's inside reads as an opening to the painted detector (its
    # bands run straight ahead), and a straight path there leaves the lane (random looks, traced:
    # 2 m off over 12 m of a 50 m bend)
    bend_straight_on: float = 0.012
    # on a painted road, the road's direction over the last metres whose samples spread more than
    # RoadHeading's 2 degrees is still its median up to this spread: a painted lane's heading at
    # a junction's mouth, where its paint ends, is the least reliable of all (random looks,
    # traced: 12.6 degrees on the frame of a plan whose last 3 m gave 2.1 with a 5.4-degree
    # spread; a lane not found there, the car 13.6 degrees askew after a drift, and a straight
    # crossing laid along the car). A kerbed carriageway's edges hold at its mouth: its lane
    # stands in, as out of a lane shift, whose samples spread far more (VIA-style seed 13: 20)
    painted_heading_spread: float = math.radians(6.0)
    handover_offset: float = 0.5  # out of a kerbed turn's arc, the lane takes over when the car is this near its middle (lane widths)
    handover_offset_painted: float = 0.25  # ... out of a painted one, when the car is at most this far right of the lane's middle
    # straight on past a lone opening of a painted road, the lane takes over from the path laid
    # straight once it has bent away from the opening (as sharply as bend_straight_on) on every
    # frame over this many metres, the car placed in it as out of a turn (handover_offset_painted):
    # the road bends at the junction, and its far side's edge line, unbroken, shows where (held-out
    # random looks, seed 309, traced: a left opening where the road bent right, its lane read
    # 0.011-0.035 1/m over 5 m, and the path laid straight left the road before its end)
    bend_away_m: float = 1.0


@dataclass
class SignMemory:
    label: str
    pos: np.ndarray  # odometry frame
    done: bool = False
    epoch: int = 0  # junctions passed when it was last seen: a turn sign is for the next junction after it


class Behaviour:
    def __init__(self, params: BehaviourParams | None = None):
        self.p = params or BehaviourParams()
        self.follow = PurePursuit(wheelbase_m=self.p.wheelbase_m, camera_forward_m=self.p.camera_forward_m)
        self.reset()

    def reset(self) -> None:
        self.state = "cruise"
        self.two_lane = True
        self.decisions: list[dict] = []  # each junction planned: what was seen, what sign, which turn
        self._dead: dict[str, bool] = {}  # dead-end verdicts of the openings ahead (see _remember_dead_ends)
        self._votes: dict[str, list[int]] = {}  # per way: [frames judging it dead, frames judging it not]
        self._dead_seen_m = -1e9  # odometer at the last frame with an opening
        # (odometer, side, opening): the closed openings of the frames before this one, oldest
        # first (at most 200: a car standing still keeps adding at one odometer reading)
        self._far_sides: deque[tuple[float, str, Opening]] = deque(maxlen=200)
        self._bends: deque[tuple[float, LaneEstimate]] = deque(maxlen=200)  # (odometer, lane found) lately
        self._plan: dict | None = None  # the last junction plan, while it may still be made again
        self._epoch = 0  # junctions passed
        self.signs: list[SignMemory] = []
        self.path: np.ndarray | None = None  # junction path, odometry frame
        self.road_heading = RoadHeading()  # the road's direction over the last metres, for laying paths
        self.lane_lateral = LaneLateral()  # ... and the lane's place beside the car, where they start
        self._arc_end: np.ndarray | None = None  # where a turn's arc (a crossing: its far side) ends on it
        self._bent_away_since: float | None = None  # odometer since which a straight path's lane bends away (bend_away_m)
        self._seen_path: np.ndarray | None = None  # the lane's centre line last traced, odometry frame
        self.turn = ""
        self.stop_sign: SignMemory | None = None
        self.stopped_since: float | None = None
        self.cooldown_until_m = -1.0
        self.follow.reset()

    # --- signs -------------------------------------------------------------------------
    def observe_signs(self, seen: list[tuple[str, np.ndarray]]) -> None:
        """Confirmed signs with positions in the odometry frame: merge into memory by place (a
        sign dealt with stays dealt with while it is still in view; a different sign at about
        the same place, as dead reckoning drifts round a loop, is a new one). Signs seen in one
        frame are different signs (a stop sign and a turn sign side by side): each memory takes
        at most one of them, its own label first; a sign of another label takes over a memory
        not yet dealt with (its confirmed class changed) only where no sign of its own was seen."""
        taken: set[int] = set()
        kept = [(label, np.asarray(pos, float)) for label, pos in seen if label in TURN_SIGNS or label == "stop"]
        unmatched = []
        for label, pos in kept:  # first each sign to a memory of its own label ...
            m = self._nearest(pos, taken, lambda m: m.label == label)
            if m is None:
                unmatched.append((label, pos))
                continue
            taken.add(id(m))
            if not m.done:
                m.pos, m.epoch = pos, self._epoch  # closer views place it better
        for label, pos in unmatched:  # ... then to one whose class it replaces, or a new one
            m = self._nearest(pos, taken, lambda m: not m.done)
            if m is None:
                m = SignMemory(label, pos, epoch=self._epoch)
                self.signs.append(m)
            else:
                m.pos, m.label, m.epoch = pos, label, self._epoch
            taken.add(id(m))

    def _nearest(self, pos: np.ndarray, taken: set[int], ok) -> SignMemory | None:
        """The nearest remembered sign within 6 m of pos that no sign of this frame has taken."""
        near = [(float(np.hypot(*(m.pos - pos))), i) for i, m in enumerate(self.signs) if id(m) not in taken and ok(m)]
        near = [c for c in near if c[0] < 6.0]
        return self.signs[min(near)[1]] if near else None

    def _ahead(self, pose: OdoPose, m: SignMemory) -> float:
        return float(pose.to_car(m.pos)[0, 1])

    def _pending(self, pose: OdoPose, labels: set[str], behind_m: float = 0.0) -> SignMemory | None:
        live = [m for m in self.signs if not m.done and m.label in labels and self._ahead(pose, m) > -behind_m]
        return min(live, key=lambda m: abs(self._ahead(pose, m)), default=None)

    # --- main step -----------------------------------------------------------------------------
    def step(self, t: float, pose: OdoPose, odo_m: float, speed: float, lane: LaneEstimate,
             junction: JunctionView | None, two_lane: bool = True) -> tuple[float, float, str]:
        """-> (steering [-1, 1], throttle [0, 1], state). `two_lane`: a painted road driven on its
        right lane (False: a kerbed carriageway driven in its middle)."""
        self.two_lane = two_lane
        # forget signs left far behind, and those dealt with once passed (out of view: a memory of
        # them could only swallow a new sign at the place dead reckoning drifts them to)
        self.signs = [m for m in self.signs if self._ahead(pose, m) > (-2.0 if m.done else -self.p.instruction_range_m)]
        self._remember_dead_ends(None if junction is not None and self._bend_view(junction, lane) else junction, odo_m)
        if self.path is None:
            self.road_heading.add(odo_m, pose.heading, lane)
            self.lane_lateral.add(odo_m, lane)
            self._remember_bend(lane, odo_m)
        if junction is not None and self._reconsider(pose, odo_m, junction):
            self.path, self.cooldown_until_m = None, -1.0  # plan this junction again, with what is known now
        if self.path is None and junction is not None and odo_m > self.cooldown_until_m:
            view = self._with_remembered_sides(self._without_unseen_cuts(junction, odo_m), junction, odo_m)
            self._plan_junction(pose, lane, self._steadied(view, odo_m) if two_lane else view, odo_m)
        if junction is not None:
            self._remember_far_sides(junction, odo_m)  # (after planning: for the frames to come)
        if self.path is not None:
            steering, throttle, state = self._junction_step(pose, odo_m, speed, lane)
            stop = self._stop(t, pose, speed)  # a stop sign before the junction still holds
            if stop is not None and stop[0] / self.p.max_speed <= throttle:
                return steering, stop[0] / self.p.max_speed, stop[1]
            return steering, throttle, state
        self.follow.lookahead, self.follow.per_mps = self.p.lookahead_painted if two_lane else self.p.lookahead_kerbed
        self.follow.max_cut_m = self.p.max_cut_painted_m if two_lane else None
        if lane.found and lane.path_m is not None and len(lane.path_m) >= 2:
            self._seen_path = pose.to_world(lane.path_m)
        steering = self.follow.step(lane, speed) if lane.found else self._follow_seen(pose, lane, speed)
        v, state = self._speed(t, pose, speed, lane)
        return steering, v / self.p.max_speed, state

    def _follow_seen(self, pose: OdoPose, lane: LaneEstimate, speed: float) -> float:
        """Steering while the lane is lost: along the centre line last traced, placed in the
        odometry frame, while some of it is still ahead (a tight bend leaves the view sideways:
        straight on from there crosses its outer kerb); then drifting back to straight."""
        if self._seen_path is not None:
            car = pose.to_car(self._seen_path)
            ahead = np.flatnonzero(car[:, 1] > 0.5)
            if len(ahead):
                d = np.hypot(car[ahead, 0], car[ahead, 1])
                i = ahead[np.argmin(np.abs(d - self.follow.lookahead_m(speed)))]
                self.follow.last = self.follow.steer_to(float(car[i, 0]), float(car[i, 1]))
                return self.follow.last
            self._seen_path = None  # driven past its end
        return self.follow.step(lane, speed)

    def _stop(self, t: float, pose: OdoPose, speed: float) -> tuple[float, str] | None:
        """Speed and state while a stop sign is pending (coast to a full stop before it, hold,
        go), or None when none is."""
        p = self.p
        stop = self._pending(pose, {"stop"})
        if stop is None:
            return None
        rem = self._ahead(pose, stop) - p.stop_before_m
        if speed < 0.05 and rem < 6.0:
            self.stopped_since = t if self.stopped_since is None else self.stopped_since
            if t - self.stopped_since >= p.stop_hold_s + p.stop_margin_s:
                stop.done = True
                self.stopped_since = None
                return p.approach_speed, "approach"
            return 0.0, "stopped"
        self.stopped_since = None
        # the fastest speed from which coasting still stops in time
        v = math.sqrt(2 * p.coast_decel * max(rem - 0.3, 0.0))
        return min(v, p.approach_speed if rem > 0 else 0.0), "stopping"

    def _speed(self, t: float, pose: OdoPose, speed: float, lane: LaneEstimate) -> tuple[float, str]:
        p = self.p
        stop = self._stop(t, pose, speed)
        if stop is not None:
            return stop
        if not lane.found:
            return p.lost_speed, "lost"
        v = p.cruise_speed
        # the bend ahead: the lane's curvature, and the sharpest circle to its traced centre line
        k = max(abs(lane.curvature), path_curvature(lane.path_m, p.curve_preview_m))
        if k > 1e-4:
            v = min(v, math.sqrt(p.lateral_accel / k))
        if self._pending(pose, TURN_SIGNS) is not None:
            return min(v, p.approach_speed), "approach"
        return v, "cruise"

    # --- junctions ------------------------------------------------------------------------------
    def _exits(self, j: JunctionView) -> set[str] | None:
        """Turns available, or None when this is not (yet) a junction: a curve opens to one
        side only and does not go on straight. A dead end is never an exit; a T-junction reached
        along its stem whose one arm is a dead end, or one whose road straight on ends, leaves one
        exit (a forced turn)."""
        sides = _sides(j)
        if not sides:
            return None
        exits = {name for name in sides if not self._dead.get(name)}
        if j.straight and not self._dead.get("straight"):
            exits.add("straight")
        if not exits:  # every way judged dead contradicts the openings seen: take the least dead,
            # the smallest share of dead verdicts, then the fewest (a T's long arm seen askew, the
            # car still turning out of a bend, reads dead on a few frames; its stub on every one)
            ways = list(sides) + (["straight"] if j.straight else [])
            votes = {w: self._votes.get(w, [0, 0]) for w in ways}
            dead = {w: (v[0] / max(sum(v), 1), v[0]) for w, v in votes.items()}
            exits = {w for w in ways if dead[w] == min(dead.values())}
        if len(exits) >= 2 or (exits and (len(sides) == 2 or self._dead.get("straight"))):
            return exits  # (one exit: the road on is a dead end, so the turn is forced)
        return None

    def choose(self, exits: set[str], instruction: str | None) -> str:
        if instruction in ("left", "right", "straight") and instruction in exits:
            return instruction
        banned = BANS.get(instruction or "", "")
        for turn in ("straight", "right", "left"):
            if turn in exits and turn != banned:
                return turn
        return sorted(exits)[0]

    def _instruction(self, pose: OdoPose, far_m: float) -> SignMemory | None:
        """The turn sign for a junction whose side road ends far_m ahead: signs stand before the
        junction they are for, so the one nearest before its far side (a sign beyond it is for
        the next junction, and must not be used up here)."""
        live = [m for m in self.signs if not m.done and m.label in TURN_SIGNS and m.epoch == self._epoch
                and -self.p.instruction_range_m < self._ahead(pose, m) < far_m + self.p.sign_slack_m]
        return max(live, key=lambda m: self._ahead(pose, m), default=None)

    def _bend(self, lane: LaneEstimate, towards: float) -> float:
        """How sharply (1/m) the lane bends towards one side (+1 right, -1 left): the traced line's
        bend as the car would steer to it, or the lane's own fitted curvature (off the lane's
        middle in an S the first reads the bend short)."""
        return max(path_bend_towards(lane.path_m, self.p.curve_preview_m, towards), towards * lane.curvature)

    def _remember_bend(self, lane: LaneEstimate, odo_m: float) -> None:
        # the lanes themselves: their bends are measured only at a plan that asks (_bent_lately)
        _forget_before(self._bends, odo_m - self.p.bend_memory_m)
        if lane.found:
            self._bends.append((odo_m, lane))

    def _bent_lately(self, way: str, odo_m: float) -> bool:
        """Did the lane bend towards `way` as sharply as a bend on a frame of the last bend_memory_m?"""
        if way not in ("left", "right"):
            return False
        towards = 1.0 if way == "right" else -1.0
        # (odometer-checked: a plan made again comes on a frame that remembered no lane)
        return any(self._bend(lane, towards) > self.p.bend_not_junction
                   for at_m, lane in self._bends if at_m >= odo_m - self.p.bend_memory_m)

    def _bends_towards(self, lane: LaneEstimate, way: str, sharper_than: float | None = None) -> bool:
        """Does the lane bend towards `way` ("left"/"right") as sharply as a bend, not a road
        running straight up to a junction (bend_not_junction, or `sharper_than`)?"""
        if not lane.found or way not in ("left", "right"):
            return False
        bend = self._bend(lane, 1.0 if way == "right" else -1.0)
        return bend > (self.p.bend_not_junction if sharper_than is None else sharper_than)

    def _bends_away(self, lane: LaneEstimate, odo_m: float) -> bool:
        """Driving straight on past a lone opening of a painted road: has the lane bent away from
        the opening on every frame of the last bend_away_m, the car placed in it (bend_away_m)?"""
        lone = self._plan["lone"] if self._plan is not None else None
        away = (self.turn == "straight" and self.two_lane and lone is not None and lane.found
                and lane.offset <= self.p.handover_offset_painted
                and self._bends_towards(lane, "right" if lone == "left" else "left", self.p.bend_straight_on))
        if not away:
            self._bent_away_since = None
            return False
        self._bent_away_since = odo_m if self._bent_away_since is None else self._bent_away_since
        return odo_m - self._bent_away_since >= self.p.bend_away_m

    def _bend_inside(self, lane: LaneEstimate, way: str, odo_m: float) -> bool:
        """Is a lone opening towards `way` the inside of a painted bend: this frame's lane bends
        towards it (bend_straight_on), or, on a frame that found no lane, a frame of the last
        bend_memory_m saw it bend towards it as sharply as a bend (_bent_lately, bend_not_junction)?
        (random looks, seeds 3 and 10, traced: a bend's lane lost on the frame its inside was
        planned as a crossing straight on, and the path laid straight along the car left the road)"""
        if lane.found:
            return self._bends_towards(lane, way, self.p.bend_straight_on)
        return self._bent_lately(way, odo_m)

    def _bend_view(self, j: JunctionView, lane: LaneEstimate) -> bool:
        """A view of a bend, not a junction: one opening, the road not going on straight, and the
        lane bending towards the opening. Its dead-end verdicts are not a junction's (via_town's
        top-right corner: three frames of "straight on ends" out of the bend itself outvoted the
        crossing just past it, whose road goes on, and sent the car into the dead-end stub)."""
        sides = list(_sides(j))
        return len(sides) == 1 and not j.straight and self._bends_towards(lane, sides[0])

    def _remember_dead_ends(self, j: JunctionView | None, odo_m: float) -> None:
        """Dead-end verdicts of the openings ahead (and of the road straight on), counted over the
        frames that could tell (far enough to see past a side road's end) up to the frame that
        plans the junction (too close to see it): a way is dead when most verdicts say so, so a
        single misjudged frame decides nothing. Forgotten once no opening has been seen for a while."""
        seen = False
        verdicts = []
        for name, o in (("left", None if j is None else j.left), ("right", None if j is None else j.right)):
            if o is not None and o.closed:
                seen = True
                verdicts.append((name, o.dead))
        if seen:
            verdicts.append(("straight", j.straight_dead))
            self._dead_seen_m = odo_m
        elif odo_m - self._dead_seen_m > self.p.dead_memory_m:
            self._votes = {}
        for name, dead in verdicts:
            if dead is not None:
                v = self._votes.setdefault(name, [0, 0])
                v[0 if dead else 1] += 1
        self._dead = {name: v[0] >= 2 and v[0] > v[1] for name, v in self._votes.items()}

    def _remember_far_sides(self, j: JunctionView, odo_m: float) -> None:
        """This frame's closed openings, for _without_unseen_cuts and _with_remembered_sides."""
        _forget_before(self._far_sides, odo_m - max(self.p.cut_seen_m, self.p.side_memory_m, self.p.steady_m))
        self._far_sides.extend((odo_m, side, o) for side, o in _sides(j).items())

    def _with_remembered_sides(self, j: JunctionView, seen: JunctionView, odo_m: float) -> JunctionView:
        """`j` with the side openings it lacks where the last frames saw them, on a frame that
        sees an opening (`seen`: the frame's own view) with the road ahead judged a dead end (see
        side_memory_m)."""
        if not self._dead.get("straight") or not _sides(seen):
            return j
        add = {}
        for side in ("left", "right"):
            if getattr(j, side) is not None:
                continue
            before = [(at_m, o) for at_m, s, o in self._far_sides
                      if s == side and not o.cut and at_m >= odo_m - self.p.side_memory_m]
            if before:
                at_m, o = before[-1]  # the latest frame's
                o = _moved_on(o, odo_m - at_m)
                if o.far_m > 0.0:  # its far side still ahead
                    add[side] = o
        return replace(j, **add) if add else j

    def _steadied(self, j: JunctionView, odo_m: float) -> JunctionView:
        """`j` with each closed side opening's ends the medians of where this frame and the frames
        of the last steady_m driven saw them (moved on by the metres driven since), over the
        openings on that side that overlap this one; its near end only from openings whose near
        end was seen (not cut). A side road's ends are fixed places on the ground, but a road
        model reads its far side patchily (random looks, traced: a crossing's far edge read 3.4 m
        early on the frame that planned the turn, 0-1 m off on the frames of the 4 m before it;
        the turn's arc began early and cut the corner across the verge)."""
        steady = {}
        for side, o in _sides(j).items():
            seen = [o] + [_moved_on(b, odo_m - at_m)
                          for at_m, s, b in self._far_sides if s == side and at_m >= odo_m - self.p.steady_m]
            seen = [b for b in seen if b.near_m < o.far_m and b.far_m > o.near_m]
            nears = [b.near_m for b in seen if not b.cut]
            steady[side] = replace(o, near_m=float(np.median(nears)) if nears else o.near_m,
                                   far_m=float(np.median([b.far_m for b in seen])))
        return replace(j, **steady) if steady else j

    def _without_unseen_cuts(self, j: JunctionView, odo_m: float) -> JunctionView:
        """The view without its cut openings that no earlier frame saw (see cut_seen_m)."""
        drop = {}
        for side, o in (("left", j.left), ("right", j.right)):
            if o is not None and o.cut and not any(
                    s == side and at_m >= odo_m - self.p.cut_seen_m
                    and abs(seen.far_m - (odo_m - at_m) - o.far_m) <= self.p.cut_far_m
                    for at_m, s, seen in self._far_sides):
                drop[side] = None
        return replace(j, **drop) if drop else j

    def _reconsider(self, pose: OdoPose, odo_m: float, j: JunctionView) -> bool:
        """Should the last junction plan be made again? Only while the car has not reached the
        junction yet, and only for news: a turn sign confirmed after a plan made without one, the
        exit a sign asks for seen after a plan made without it (a side road comes into view
        later than the other side's), or a dead end found (later, from closer) on the way the
        plan takes."""
        plan = self._plan
        if plan is not None and odo_m > plan["odo_m"] + plan["far_m"]:
            self._plan, self._dead, self._votes = None, {}, {}  # past that junction: its verdicts are not the next one's
            self._epoch += 1  # and the turn signs seen before it were for it ...
            if plan["turn"] == "straight":
                # ... except those standing beyond its far side (with slack, as _instruction
                # leaves them): junctions a few metres apart put the next one's sign there, and
                # the car may see it last before the first junction
                far_ahead = plan["odo_m"] + plan["far_m"] - odo_m + self.p.sign_slack_m
                for m in self.signs:
                    if m.epoch == self._epoch - 1 and not m.done and self._ahead(pose, m) > far_ahead:
                        m.epoch = self._epoch
            return False
        if plan is None or odo_m > plan["until_m"]:
            return False
        if plan["sign"] is None and self._instruction(pose, plan["far_m"] - (odo_m - plan["odo_m"])) is not None:
            return True
        if plan["sign"] in ("left", "right", "straight") and plan["turn"] != plan["sign"]:
            exits = self._exits(j)
            if exits is not None and plan["sign"] in exits:
                self._sign_again(plan)
                return True
        # (a turn planned as the least dead of ways all judged dead is not news when judged so again)
        if self._dead.get(plan["turn"]) and not plan["dead_at_plan"]:
            self._sign_again(plan)  # (planned again without it, a "no right" T's left arm judged dead went right)
            return True
        return False

    def _sign_again(self, plan: dict) -> None:
        """The sign a plan used is for the same junction when it is planned again."""
        sign = plan["memory"]
        if sign is None:
            return
        sign.done = False
        if all(m is not sign for m in self.signs):
            self.signs.append(sign)  # (dropped once it was dealt with and passed)

    def _plan_junction(self, pose: OdoPose, lane: LaneEstimate, j: JunctionView, odo_m: float = 0.0) -> bool:
        exits = self._exits(j)
        if exits is None:
            return False
        sides = _sides(j)
        side = list(sides.values())
        near = min(o.near_m for o in side)
        # (VIA's camera shows a painted road's left side from about 12 m on: an opening there
        # begins at the view's edge, its near end unseen, and is as close as it can be seen)
        if near > self.p.commit_near_m and not (near <= self.p.commit_cut_m and all(o.cut for o in side)):
            return False
        if lane.found and abs(lane.heading) > self.p.aligned_rad and near > self.p.commit_late_m:
            return False  # still turning out of a bend (or a lane shift): what it sees of the junction is askew
        if len(exits) == 1 and len(side) == 1 and (self._bends_towards(lane, next(iter(exits))) or (
                self.two_lane and self._bent_lately(next(iter(exits)), odo_m))):
            return False  # (a kerbed carriageway's corners are driven as turns: VIA's are chamfered)
        # the path is laid along the road, not along the car (heading > 0: the car points right
        # of it): the road's direction over the last metres, else this frame's lane. Out of a
        # bend the car meets the junction askew, and the side road's ends it sees ahead lie at
        # other distances along the road (via_town, the curved street's end: 20 degrees askew,
        # the crossing's middle seen 0.6 m further on than it is, and the right turn made late).
        # When to plan stays judged on what the car sees: a frame whose lane heading is misread
        # would otherwise move a far junction near enough to plan
        heading = self.road_heading.car_heading(odo_m, pose.heading)
        if heading is None and self.two_lane:
            heading = self.road_heading.car_heading(odo_m, pose.heading, self.p.painted_heading_spread)
        # a plan made again (news before the junction) on a kerbed carriageway is for the same
        # road: where the road's direction is not known now, the one the plan it replaces was
        # laid along, not this frame's lane. The road's direction gathers no samples while a
        # plan is driven (random looks, VIA style, seed 14, traced: a right turn planned at the
        # start, its arm found dead 2.6 m on; the left turn made again along a frame's lane read
        # 11.6 degrees askew (the frames before it: from 3.7 degrees one way to 13.6 the other),
        # and the car swung right first and left the road 1.9 m wide of the turn). Not on a
        # painted road, whose direction comes from its median up to painted_heading_spread first:
        # a painted plan's own direction can be a bend's frame (dev seed 105: a straight plan in a
        # left bend, made again as a right turn along it, left the road; along its frame's lane not)
        again = self._plan if self._plan is not None and odo_m <= self._plan["until_m"] else None
        if heading is None and not self.two_lane and again is not None and again["road_dir"] is not None:
            heading = float(wrap_pi(again["road_dir"] - pose.heading))
        heading = heading if heading is not None else (lane.heading if lane.found else None)
        side = [_along_road(o, heading) for o in side]
        y_c = float(np.mean([o.centre_m for o in side]))
        far = max(o.far_m for o in side)
        sign = self._instruction(pose, far)
        if sign is not None and not _sign_fits(exits, sign.label):
            # the sign's way is not among the ways seen, or it bans the only one: the junction is
            # misread (a random look, traced: a T's left arm unseen on the frame its right arm
            # came near, and a "no right" T taken right). Read it again on the next frames ...
            if near > self.p.commit_late_m:
                return False
            # ... and once near, a way seen but judged dead that obeys the sign is taken: the sign
            # says it is there (random looks: a "no right" T whose left arm read dead, taken right)
            seen = set(sides) | ({"straight"} if j.straight else set())
            obeying = {w for w in seen if _sign_fits({w}, sign.label)}
            exits = obeying or exits
        self.turn = self.choose(exits, sign.label if sign else None)
        if sign is not None:
            sign.done = True
        self.decisions.append({"odo_m": round(odo_m, 1), "exits": sorted(exits), "sign": sign.label if sign else None,
                               "turn": self.turn, "near_m": round(near, 1),
                               "dead": sorted(n for n, d in self._dead.items() if d)})
        self._plan = {"odo_m": odo_m, "until_m": odo_m + max(near - self.p.replan_margin_m, 0.0), "far_m": far,
                      "sign": sign.label if sign else None, "memory": sign, "turn": self.turn,
                      "dead_at_plan": bool(self._dead.get(self.turn)),
                      "lone": next(iter(sides)) if len(sides) == 1 else None,  # a lone opening's side (_bends_away)
                      # the road's direction (odometry frame, radians CCW) the path is laid along
                      "road_dir": None if heading is None else pose.heading + heading}
        if self.turn == "straight" and (not self.two_lane or (len(sides) == 1 and self._bend_inside(
                lane, next(iter(sides)), odo_m))):
            # a kerbed carriageway's edges carry on across a junction (the far edge stands in
            # for the open one), as a painted bend's lane does past a lone opening on its inside:
            # keep following it, and judge no junction until past this one
            self.cooldown_until_m = odo_m + far + 1.0
            return False
        lateral = self.lane_lateral.lateral_m(odo_m)
        if lateral is None:
            lateral = -lane.offset * (lane.lane_width_m or self.p.lane_width_m) if lane.found else 0.0
        path = _junction_path(self.turn, y_c, lateral, self.p, self.two_lane)
        if heading is not None:
            path = _rotate(path, heading)
        self.path = pose.to_world(path)
        # where the turn's arc ends (its straight tail follows), or a straight crossing's far side
        # (where the exit road's paint begins): past it, the exit road's own lane may lead on
        self._arc_end = self.path[-len(_TAIL_X) - 1] if self.turn != "straight" else \
            self.path[min(int(far / _PATH_STEP_M), len(self.path) - 1)]
        self._seen_path = None  # traced before the junction: not the way out of it
        self._bent_away_since = None
        self.follow.reset()
        return True

    def _junction_step(self, pose: OdoPose, odo_m: float, speed: float, lane: LaneEstimate
                       ) -> tuple[float, float, str]:
        car = pose.to_car(self.path)
        ahead = np.flatnonzero(car[:, 1] > 0.5)
        remaining = np.hypot(*np.diff(self.path[ahead[0]:], axis=0).T).sum() if len(ahead) else 0.0
        # out of a turn the exit road's own lane leads on, once the car is past the arc and sees
        # it where it should be: the tail laid straight out of the arc runs into whatever the exit
        # road does next (a lane shift one tile on: its lane then points well askew, so it is the
        # offset, not the heading, that says the lane is the exit road's). A kerbed carriageway:
        # the car inside its edges. A painted road: the lane found is the right one or to the
        # right of the car (a tail laid from a misjudged side road can put the car on the centre
        # line, and the lane left of it, found as readily there, is the wrong way's). Straight
        # across a painted crossing likewise, past its far side: a path laid a few degrees askew
        # would otherwise carry the car on to the path's end, up to 1.8 m off its lane
        out_of_arc = (self._arc_end is not None and lane.found and pose.to_car(self._arc_end[None])[0, 1] < 0.0
                      and (lane.offset <= self.p.handover_offset_painted if self.two_lane
                           else abs(lane.offset) <= self.p.handover_offset))
        bent_away = self._bends_away(lane, odo_m)
        if not len(ahead) or remaining < 5.0 or out_of_arc or bent_away:
            self.path = None
            self.cooldown_until_m = odo_m + 6.0
            if bent_away:  # (handed over before the opening's far side: no junction judged until past it)
                self.cooldown_until_m = max(self.cooldown_until_m, self._plan["odo_m"] + self._plan["far_m"] + 1.0)
            return 0.0, self.p.approach_speed / self.p.max_speed, "cruise"
        lookahead = 3.0 + 0.3 * speed
        d = np.hypot(car[:, 0], car[:, 1])
        i = ahead[np.argmin(np.abs(d[ahead] - lookahead))]
        steering = self.follow.steer_to(float(car[i, 0]), float(car[i, 1]))
        v = self.p.junction_speed if self.turn != "straight" else self.p.approach_speed
        return steering, v / self.p.max_speed, f"junction-{self.turn}"


_PATH_STEP_M = 0.25  # junction paths are sampled this often
_TAIL_X = np.arange(_PATH_STEP_M, 12.0, _PATH_STEP_M)  # a turn's straight tail out of its arc, metres


def _forget_before(memory: deque, odo_m: float) -> None:
    """Drop a memory's entries, (odometer, ...) oldest first, from before the odometer odo_m."""
    while memory and memory[0][0] < odo_m:
        memory.popleft()


def _moved_on(o: Opening, driven_m: float) -> Opening:
    """An opening seen driven_m metres of odometer ago, placed relative to the car now."""
    return replace(o, near_m=o.near_m - driven_m, far_m=o.far_m - driven_m)


def _sides(j: JunctionView) -> dict[str, Opening]:
    """The side openings of a view whose far edge was seen (closed), by way ("left", "right")."""
    return {name: o for name, o in (("left", j.left), ("right", j.right)) if o is not None and o.closed}


def _sign_fits(exits: set[str], label: str) -> bool:
    """Can a turn sign be obeyed at a junction with these exits: its way among them, or a way
    other than the one it bans?"""
    if label in ("left", "right", "straight"):
        return label in exits
    banned = BANS.get(label)
    return banned is None or bool(exits - {banned})


def _along_road(o: Opening, heading: float | None) -> Opening:
    """An opening seen from a car pointing `heading` radians right of the road, with its near
    and far ends as distances along the road (where the side road's edges cross the road's axis
    through the car: lines across the road, seen at ground x = o.x_m of the car's frame)."""
    if heading is None or heading == 0.0:
        return o
    c, s = math.cos(heading), math.sin(heading)
    return replace(o, near_m=c * o.near_m - s * o.x_m, far_m=c * o.far_m - s * o.x_m)


def _rotate(path: np.ndarray, heading: float) -> np.ndarray:
    """Car-frame points of a path laid out along a road the car points `heading` radians right
    of (the road's axes turned left by that angle, about the car)."""
    c, s = math.cos(heading), math.sin(heading)
    return np.column_stack([c * path[:, 0] - s * path[:, 1], s * path[:, 0] + c * path[:, 1]])


def _junction_path(turn: str, y_c: float, lateral_m: float, p: BehaviourParams, two_lane: bool = True) -> np.ndarray:
    """The path through a junction in the car frame (x right, y ahead), from the car's lane
    (lateral_m: the lane centre's x) to the chosen exit lane, sampled every 0.25 m. On a
    two-lane road the exit lane is the right one of the side road; on a kerbed carriageway its
    middle, reached with the same radius either way."""
    if turn == "straight":
        ys = np.arange(0.0, y_c + 10.0, _PATH_STEP_M)
        return np.column_stack([np.full_like(ys, lateral_m), ys])
    r, y_exit, sgn = _turn(turn, y_c, p, two_lane)
    y0 = max(y_exit - r, 0.5)
    lead = np.column_stack([np.full(int(y0 / _PATH_STEP_M) + 1, lateral_m), np.linspace(0, y0, int(y0 / _PATH_STEP_M) + 1)])
    a = np.linspace(0, math.pi / 2, max(8, int(r * math.pi / 2 / _PATH_STEP_M)))
    arc = np.column_stack([lateral_m + sgn * r * (1 - np.cos(a)), y0 + r * np.sin(a)])
    tail = np.column_stack([arc[-1, 0] + sgn * _TAIL_X, np.full_like(_TAIL_X, arc[-1, 1])])
    return np.concatenate([lead, arc, tail])


def _turn(turn: str, y_c: float, p: BehaviourParams, two_lane: bool) -> tuple[float, float, float]:
    """(radius, the exit lane's y, +1 right / -1 left) of a turn at a junction centred y_c ahead."""
    h = p.lane_width_m / 2 if two_lane else 0.0
    if turn == "right":
        return (p.right_radius_m if two_lane else p.kerbed_radius_m), y_c - h, 1.0
    return (p.left_radius_m if two_lane else p.kerbed_radius_m), y_c + h, -1.0

