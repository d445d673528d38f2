"""The road's direction in the odometry frame, remembered over the last metres driven.

A junction's path is laid along the road, not along the car. One frame's lane heading at the
junction's mouth is the least reliable of all: the paint that fixes it ends there (painted
`via_town`'s central crossroads, traced: +5.9 degrees one frame, -2.0 the next, at the frame the
straight crossing was planned from, and the crossing ended 1.8 m right, on the exit road's edge
line). Every frame the lane is found, the road's direction in the odometry frame (the car's
odometry heading plus the lane's heading) is one sample of it; their median over the last few
metres gives the road's direction where the car is now, and so the car's heading against it,
when they agree (a road that turned inside those metres has no one direction: then this frame's
lane heading is used, as before).
(A straight-line fit against the odometer, tried first, follows a bend better but carries a bend
that ends at the junction's mouth on past its end: 8.0 degrees from samples of 5.3-6.6 there.)

The lane's lateral place, where a junction's path starts from, is remembered the same way
(`LaneLateral`): one frame's lane at the junction's mouth can be any other line's (a random look
in shadow, traced: a 2.2 m "lane" put the path 1.2 m right of the car, which followed it onto the
edge line).
"""
from __future__ import annotations

import math
from collections import deque

import numpy as np

from signlane.angles import wrap_pi
from signlane.types import LaneEstimate


class RoadHeading:
    """Samples of the road's direction (radians, counter-clockwise, the odometry frame) against the
    odometer. `window_m`: how far back samples count; an answer needs `min_samples` of them spread
    over `min_span_m`, from frames whose lane confidence is at least `min_confidence`, at most one
    per `step_m` driven, and agreeing: their robust spread (1.4826 x the median absolute
    deviation) at most `max_spread` radians. (A lane whose one line is found and the other placed
    a lane width from it has confidence 0.5: at 0.8, random looks with a worn edge line left no
    sample in the 3 m before most junctions, and the path was laid along one frame's lane.)"""

    def __init__(self, window_m: float = 3.0, min_samples: int = 8, min_span_m: float = 1.5,
                 min_confidence: float = 0.5, step_m: float = 0.1, max_spread: float = math.radians(2.0)):
        self.window_m, self.min_samples, self.min_span_m = window_m, min_samples, min_span_m
        self.min_confidence, self.step_m, self.max_spread = min_confidence, step_m, max_spread
        self._samples: deque[tuple[float, float]] = deque()

    def add(self, odo_m: float, car_heading: float, lane: LaneEstimate) -> None:
        """One frame: the odometer (m), the car's odometry heading (radians CCW) and its lane."""
        # one sample per `step_m` driven: a car waiting at a stop line would otherwise fill the
        # window with one view of the junction's mouth
        moved = not self._samples or odo_m - self._samples[-1][0] >= self.step_m
        if moved and lane.found and lane.confidence >= self.min_confidence and math.isfinite(lane.heading):
            # heading > 0: the car points right of the road, so the road points left of the car (CCW +)
            self._samples.append((odo_m, car_heading + lane.heading))
        while self._samples and self._samples[0][0] < odo_m - self.window_m:
            self._samples.popleft()

    def car_heading(self, odo_m: float, car_heading: float, max_spread: float | None = None) -> float | None:
        """The car's heading against the road at the odometer odo_m (radians, + the car points
        right of it, as LaneEstimate.heading), or None with too few samples or samples that
        disagree (spread more than `max_spread`, by default the tracker's)."""
        recent = [(d, a) for d, a in self._samples if d >= odo_m - self.window_m]
        if len(recent) < self.min_samples or recent[-1][0] - recent[0][0] < self.min_span_m:
            return None
        # each against the car's heading now, wrapped to (-pi, pi]: no seam inside the median
        rel = wrap_pi(np.array([a for _, a in recent]) - car_heading)
        mid = float(np.median(rel))
        # a road that turned inside the window (a lane shift or a bend just before the junction)
        # has no one direction: say nothing, rather than a median of two roads (VIA-style seed 13:
        # samples from -38 to +15 degrees out of a lane shift, the median -19, the turn laid 34
        # degrees askew and the car over the kerb)
        if 1.4826 * float(np.median(np.abs(rel - mid))) > (self.max_spread if max_spread is None else max_spread):
            return None
        return mid


class LaneLateral:
    """Where the lane's centre lies beside the car (metres, + right), remembered over the last
    `window_m` driven: the median of the frames' lanes there, from at least `min_samples` frames.
    A frame's lane further than `max_jump_m` from the median of those before it is left out: a
    car following its lane does not move sideways that fast, a misread lane does (random looks,
    traced: at a crossing's mouth the paint method took the side road's lines for the lane on
    five frames in a row, 1-1.2 lane widths right of it, and their median put a straight path's
    start 3.8 m right of the car)."""

    def __init__(self, window_m: float = 2.0, min_samples: int = 4, max_jump_m: float = 0.8):
        self.window_m, self.min_samples, self.max_jump_m = window_m, min_samples, max_jump_m
        self._samples: deque[tuple[float, float]] = deque()

    def add(self, odo_m: float, lane: LaneEstimate) -> None:
        while self._samples and self._samples[0][0] < odo_m - self.window_m:
            self._samples.popleft()
        if lane.found and math.isfinite(lane.offset) and lane.lane_width_m > 0:
            # offset > 0: the car is right of the lane's centre, so the centre is left of the car
            x = -lane.offset * lane.lane_width_m
            if len(self._samples) >= self.min_samples and \
                    abs(x - float(np.median([v for _, v in self._samples]))) > self.max_jump_m:
                return
            self._samples.append((odo_m, x))

    def lateral_m(self, odo_m: float) -> float | None:
        """The lane centre's lateral place at the odometer odo_m, or None with too few samples."""
        recent = [x for d, x in self._samples if d >= odo_m - self.window_m]
        return float(np.median(recent)) if len(recent) >= self.min_samples else None
