"""The proposals' search is bounded: textured ground of a sign colour (red soil, bricks, a red
road under sensor noise) breaks into ever more pieces at each saturation level, and searching
all of them cost up to 160 ms a frame. Levels that hold the same pixels are searched once, a
blob's hundreds of pinholes are no ring interiors, and each search stops after a budget of
levels and contours, largest boxes first. The signs must still be found."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from signlane.signs import proposals
from signlane.signs.proposals import ProposalParams, box_iou, propose


@pytest.fixture(scope="module")
def soil_frame():
    """A drive frame of our renderer on red-brown textured ground, with a stop sign ahead."""
    from signlane.world.sampling import DriveSampler, SamplerConfig
    return DriveSampler(4, SamplerConfig(640, 480, style="via", effects="normal")).sample(270).image


def test_textured_ground_walks_few_holes_searches_each_level_once_and_keeps_the_sign(soil_frame, monkeypatch):
    walked, searched = [], []
    real_rings, real_level = proposals._rings_in_holes, proposals._search_level

    def rings(contours, hier, parent, ctx, win):
        walked.append(int((hier[:, 3] == parent).sum()))
        return real_rings(contours, hier, parent, ctx, win)

    def level(win, s_min, roi, color, ctx, *args):
        searched.append((ctx.W, color, s_min, roi))
        return real_level(win, s_min, roi, color, ctx, *args)
    monkeypatch.setattr(proposals, "_rings_in_holes", rings)
    monkeypatch.setattr(proposals, "_search_level", level)
    capped = propose(soil_frame)
    holes = sum(walked)
    walked.clear()
    assert len(searched) == len(set(searched))  # no box is searched twice at one level
    monkeypatch.setattr(proposals, "RING_HOLES", 10 ** 9)
    uncapped = propose(soil_frame)
    assert holes < 0.2 * sum(walked)  # measured: 1,505 holes walked against 11,728
    assert capped == uncapped  # on this frame the same proposals
    stop = capped[0]  # the stop sign on the horizon, about 21 px
    assert stop.color == "red" and stop.score > 0.9 and 18 <= stop.box[2] <= 30


def test_levels_that_hold_the_same_pixels_are_searched_once(monkeypatch):
    # a flat, fully saturated red wall (not sign-shaped), unblurred: every level up to its
    # saturation is the same mask, so one search of it is all it gets (seven before; with the
    # blur its edge pixels differ from level to level)
    img = np.full((240, 320, 3), 90, np.uint8)
    img[60:120, 20:300] = (20, 20, 200)
    levels = []
    real = proposals._search_level

    def level(win, s_min, roi, *args):
        levels.append(s_min)
        return real(win, s_min, roi, *args)
    monkeypatch.setattr(proposals, "_search_level", level)
    assert propose(img, ProposalParams(regions=False, blur_px=0)) == []
    assert levels == [40, 40]  # red once, blue once (nothing of it found)


def test_a_blob_with_hundreds_of_holes_is_not_walked_for_rings(monkeypatch):
    # red ground with 400 pinholes bigger than the hole floor: not a wall around a ring sign
    img = np.full((480, 640, 3), 90, np.uint8)
    img[200:460, 20:620] = (30, 30, 200)
    for y in range(210, 450, 12):
        for x in range(30, 610, 15):
            img[y:y + 6, x:x + 6] = 90
    walked = []
    real = proposals._rings_in_holes
    monkeypatch.setattr(proposals, "_rings_in_holes", lambda *a: walked.append(1) or real(*a))
    propose(img, ProposalParams(regions=False))
    assert walked == []
    img[210:450, 30:610] = (30, 30, 200)  # the same wall with one ring-like hole walks it
    cv2.circle(img, (320, 330), 30, (220, 220, 220), -1)
    propose(img, ProposalParams(regions=False))
    assert walked
