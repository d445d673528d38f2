"""The region search of the proposals (signlane/signs/roi.py): a half-size pass says where to
look, the full-resolution search runs there only. It must find the signs the full-frame search
finds, with the same boxes, and its blurred HSV must be the full frame's pixel for pixel."""
from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest

from signlane.signs import roi
from signlane.signs.eval_proposals import MAX_OCCLUDED, _match, rendered_frames
from signlane.signs.proposals import ProposalParams, propose


@pytest.mark.parametrize("shape", [(480, 640), (241, 333), (17, 9)])
def test_region_hsv_is_the_full_frame_blur_pixel_for_pixel(shape):
    img = np.random.default_rng(0).integers(0, 256, shape + (3,), dtype=np.uint8)
    full = cv2.cvtColor(cv2.GaussianBlur(img, (3, 3), 0), cv2.COLOR_BGR2HSV)
    assert np.array_equal(roi.sparse_blurred_hsv(img, 8, 3), full[::8, ::8])
    out = np.zeros_like(img)
    for box in [(0, 0, shape[1], shape[0]), (3, 2, min(shape[1], 60), min(shape[0], 40)),
                (shape[1] // 2, shape[0] // 2, shape[1], shape[0])]:
        roi.blurred_hsv(img, box, 3, out)
        x0, y0, x1, y1 = box
        assert np.array_equal(out[y0:y1, x0:x1], full[y0:y1, x0:x1]), box


def test_windows_are_clipped_and_merged():
    # two overlapping coarse boxes make one window; a far one its own; all inside the frame
    w = roi.windows([(10, 10, 20, 20), (25, 12, 10, 10), (250, 200, 20, 20)], (2.0, 2.0), (640, 480), 16)
    assert len(w) == 2
    for x0, y0, x1, y1 in w:
        assert 0 <= x0 < x1 <= 640 and 0 <= y0 < y1 <= 480
    near = min(w)
    assert near[0] <= 20 and near[2] >= 70 and near[1] <= 20 and near[3] >= 64  # both boxes, padded


@pytest.fixture(scope="module")
def sign_frames():
    return list(rendered_frames(60, 1000, False, 640, 480, focus="signs"))


def test_region_search_finds_the_full_frame_signs_with_the_same_boxes(sign_frames):
    full, fast = ProposalParams(regions=False), ProposalParams()
    assert fast.regions and not ProposalParams.published().regions
    found_full = found_fast = same_frames = 0
    for img, signs in sign_frames:
        a, b = propose(img, full), propose(img, fast)
        same_frames += a == b
        half = cv2.resize(img, (320, 240), interpolation=cv2.INTER_AREA)
        assert propose(img, fast, half) == b  # the caller's half-size copy is the one it makes
        eligible = [s for s in signs if s.occluded <= MAX_OCCLUDED and min(s.box[2], s.box[3]) >= 20]
        ma, mb = _match(eligible, a), _match(eligible, b)
        found_full += len(ma)
        found_fast += len(mb)
        for i in set(ma) & set(mb):  # a sign both find has one box, to the pixel
            assert np.abs(np.subtract(a[ma[i]].box, b[mb[i]].box)).max() <= 1
    assert found_full >= 20  # the set holds signs
    assert found_fast >= found_full - 1
    assert same_frames >= 0.75 * len(sign_frames)


def test_region_search_falls_back_to_its_own_half_copy_on_odd_sizes(sign_frames):
    img = sign_frames[0][0][:479, :639]
    wrong = np.zeros((100, 100, 3), np.uint8)  # not half this frame: ignored
    assert propose(img, ProposalParams(), wrong) == propose(img, ProposalParams())
    assert replace(ProposalParams(), regions=False).regions is False
