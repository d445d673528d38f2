"""The image rows where a sign face can stand, for a camera on a car (the drive stack's sign search).

A driving camera sees sign faces at a known height above a flat road: VIA's faces are 1.25 m
squares centred 2.42 m up, and its camera is 2.9 m up, pitched 11.8 degrees down, so every face
further than a few metres ahead lies in a band of rows around the horizon. Below that band is
road and ground (VIA's brown soil and grass gave the colour search about 200 specks a frame),
above it sky. The search then looks at the band only: a face nearer than `near_m` may fall
outside it, but the stack has confirmed and placed a sign long before the car is that close.
"""
from __future__ import annotations

import logging
import math

import numpy as np

from signlane.camera import Camera

log = logging.getLogger(__name__)


def face_rows(camera: Camera, near_m: float, low_m: float, high_m: float, margin_deg: float = 3.0
              ) -> tuple[int, int] | None:
    """(top, bottom) image rows, bottom exclusive, clipped to the frame: where a point between
    low_m and high_m above the road, at least near_m ahead of the camera and inside its view,
    can be seen, widened by margin_deg of pitch each way (the car pitching on its springs, a
    camera mounted a little off). None when near_m <= 0 (search every row)."""
    if near_m <= 0:
        return None
    half_w = math.tan(math.radians(camera.hfov_deg) / 2.0)
    points = []
    for ahead in (near_m, 1e4):  # a face's rows are furthest from the horizon when it is nearest
        for side in (-1.0, 0.0, 1.0):  # the frame's edges and middle: they differ when the camera rolls
            for z in (low_m, high_m):
                points.append((side * half_w * ahead, ahead, z))
    pix, depth = camera.project(np.array(points))
    rows = pix[depth > 0, 1]
    margin = camera.focal_px * math.tan(math.radians(margin_deg))
    top = max(0, int(math.floor(rows.min() - margin)))
    bottom = min(camera.height, int(math.ceil(rows.max() + margin)) + 1)
    return top, max(top, bottom)


class RowBand:
    """The rows the sign stage searches, checked against what it finds. The band is right only
    when the camera settings match the frames; a wrong camera would hide every sign, silently.
    So one frame in `check_every` is also searched on every row, and a sign the classifier reads
    reaching outside the band on `misses` such frames means the settings do not match (with
    them, a face reaches out of the band only nearer than the band's near distance, where the
    side of the view has cut it off long before): the band is given up, with a warning, and
    every row is searched from then on. The frame itself is answered from the band as every
    other frame is; the whole-row search is the check's alone, made once the frame's command is
    out (SignStage.settle), so a check frame costs the steering path no more than any other."""

    def __init__(self, size: tuple[int, int], rows: tuple[int, int], check_every: int = 15, misses: int = 2):
        self.size, self.rows = size, rows
        self.check_every, self.misses = check_every, misses
        self.frames = self.outside = 0
        self.given_up = False
        self.due = False  # the last frame given rows_for is to be checked on every row

    def rows_for(self, size: tuple[int, int]) -> tuple[int, int] | None:
        """The rows to search on the next frame (of (width, height) `size`); None: every row.
        Sets `due` when that frame is also to be searched on every row for the check."""
        self.frames += 1
        if self.given_up or size != self.size:
            self.due = False
            return None
        self.due = self.frames % self.check_every == 0
        return self.rows

    def outside_band(self, box) -> bool:
        """Does an (x, y, w, h) box reach above or below the band?"""
        top, bottom = self.rows
        return box[1] < top or box[1] + box[3] > bottom

    def check(self, size: tuple[int, int], signs) -> None:
        """After a due frame's search on every row: its signs the classifier read (x, y, w, h boxes)."""
        if self.given_up or size != self.size:
            return
        if any(self.outside_band(d.box) for d in signs):
            self.outside += 1
            if self.outside >= self.misses:
                self.given_up = True
                top, bottom = self.rows
                log.warning("signs seen outside image rows %d-%d, where the camera settings put every sign face; "
                            "camera.* may not match this camera: searching every row from now on", top, bottom)
