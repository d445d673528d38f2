"""`auto` (the default): follow whatever the road offers, told apart from the image itself.

Every frame `road-edges` finds the carriageway and keeps a running measure of whether a centre
line is painted along its middle. On a kerbed carriageway with no centre line (VIA's road) the
lane is the carriageway and the car keeps its middle. On a two-lane road with a centre line the
lane is the right one, from the paint (`sliding-window`), or, where the paint is not found, the
right half of the carriageway. `LaneEstimate.basis` says which ("edges" or "paint").
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import cv2
import numpy as np

from signlane.camera import Camera
from signlane.lanes import register
from signlane.lanes.geometry import Boundary, camera_for, estimate_from_fits
from signlane.lanes.road_edges import RoadEdgesParams, RoadEdgesState, carriageway, carriageway_estimate
from signlane.lanes.sliding_window import SlidingWindowParams, SlidingWindowState, sliding_window
from signlane.types import LaneEstimate

NAME = "auto"


@dataclass(frozen=True)
class AutoParams:
    road: RoadEdgesParams = field(default_factory=RoadEdgesParams)
    paint: SlidingWindowParams = field(default_factory=SlidingWindowParams)

    @classmethod
    def published(cls) -> "AutoParams":
        return cls()


@dataclass(frozen=True)
class AutoState:
    road: RoadEdgesState = field(default_factory=RoadEdgesState)
    paint: SlidingWindowState | None = None

    @property
    def two_lane(self) -> bool:
        return self.road.two_lane

    def forget_tracks(self) -> "AutoState":
        return AutoState(self.road.forget_tracks(), None)


@register(NAME, AutoParams)
def auto(image_bgr: np.ndarray, camera: Camera | None, params: AutoParams,
         state: AutoState | None) -> tuple[LaneEstimate, AutoState]:
    image_bgr = image_bgr if image_bgr.ndim == 3 else cv2.cvtColor(image_bgr, cv2.COLOR_GRAY2BGR)
    h, w = image_bgr.shape[:2]
    state = state or AutoState()
    if min(h, w) < 16:
        return LaneEstimate(NAME, False, debug_mask=np.zeros((h, w), np.uint8)), state
    cam = camera_for(image_bgr, camera)
    left, right, width, road_state, mask = carriageway(image_bgr, cam, params.road, state.road)
    if not road_state.two_lane:
        return carriageway_estimate(NAME, cam, left, right, width, road_state, mask, (h, w)), AutoState(road_state, None)
    est, paint_state = sliding_window(image_bgr, cam, params.paint, state.paint)
    if est.found:
        return replace(est, method=NAME, basis="paint"), AutoState(road_state, paint_state)
    # no paint found this frame: the right half of the carriageway
    mid = None if left is None or right is None else Boundary((left.coeffs + right.coeffs) / 2, left.y_range)
    debug = mask if mask is not None else np.zeros((h, w), np.uint8)
    est = estimate_from_fits(NAME, cam, mid, right, width / 2, 0.5 if mid is not None else None, debug)
    return replace(est, basis="edges"), AutoState(road_state, paint_state)


def road_state(state) -> RoadEdgesState | None:
    """The road-edges state inside a lane method's state (auto or road-edges), else None."""
    if isinstance(state, AutoState):
        return state.road
    return state if isinstance(state, RoadEdgesState) else None
