"""Frozen dataclasses that flow between stages: Frame -> LaneEstimate/SignDetection -> Command.

Units and signs everywhere: `offset` is the car's lateral offset from the ego-lane centre as a
fraction of lane width, positive when the car is right of centre; `heading` is radians between
the car's axis and the lane direction, positive when the car points to the right of the lane;
`curvature` is 1/metres, positive when the road bends right. Steering in [-1, 1], positive right.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np


@dataclass(frozen=True)
class Frame:
    """One camera frame: image_bgr is uint8 (H, W, 3) BGR."""

    image_bgr: np.ndarray
    t: float = 0.0
    seq: int = 0


@dataclass(frozen=True)
class LaneEstimate:
    """What a lane method reports. Boundary polylines are (N, 2) float image pixels or None."""

    method: str
    found: bool
    offset: float = 0.0
    heading: float = 0.0
    curvature: float = 0.0
    confidence: float = 0.0
    left: np.ndarray | None = None
    right: np.ndarray | None = None
    debug_mask: np.ndarray | None = None
    lane_width_m: float = 0.0  # measured (or nominal) width; 0 = unknown
    basis: str = "paint"  # what the boundaries are: "paint" (lane lines) | "edges" (the road's own edges)
    # the lane's centre line as the method traced it, ground metres (x right, y ahead), near to
    # far, or None: followed directly where a fitted curve cannot bend as tightly as the road
    path_m: np.ndarray | None = None
    # uint8 (H, W) 0/255 road surface at the frame's size, from a method with a road output
    # (segnet's road model, road-edges), else None
    drivable_mask: np.ndarray | None = None
    # the two masks above, put off: frame-sized arrays only a viewer reads (infer's written masks,
    # the monitor), made by `with_masks` where one is wanted; the car never pays for them
    masks_later: Callable[[], tuple[np.ndarray | None, np.ndarray | None]] | None = \
        field(default=None, repr=False, compare=False)

    def with_masks(self) -> "LaneEstimate":
        """This estimate with the masks it put off made (itself when it put none off)."""
        if self.masks_later is None:
            return self
        debug, drivable = self.masks_later()
        return replace(self, debug_mask=debug, drivable_mask=drivable, masks_later=None)


@dataclass(frozen=True)
class SignDetection:
    """A sign (or a proposal): box is (x, y, w, h) in image pixels."""

    label: str
    score: float
    box: tuple[int, int, int, int]
    color: str = ""


@dataclass(frozen=True)
class Perception:
    frame: Frame
    lane: LaneEstimate
    signs: tuple[SignDetection, ...] = ()
    timing_ms: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class Command:
    steering: float
    throttle: float
    state: str = "cruise"
