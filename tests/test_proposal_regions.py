"""The region search of the proposals (signlane/signs/roi.py): a half-size pass says where to
look, the full-resolution search runs there only. It must find the signs the full-frame search
finds, with the same boxes, and its blurred HSV must be the full frame's pixel for pixel."""
from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest

from signlane.signs import planes, proposals, roi
from signlane.signs.eval_proposals import MAX_OCCLUDED, _match, rendered_frames
from signlane.signs.proposals import ProposalParams, propose


@pytest.mark.parametrize("shape", [(480, 640), (241, 333), (17, 9)])
def test_region_hsv_is_the_full_frame_blur_pixel_for_pixel(shape):
    img = np.random.default_rng(0).integers(0, 256, shape + (3,), dtype=np.uint8)
    full = cv2.cvtColor(cv2.GaussianBlur(img, (3, 3), 0), cv2.COLOR_BGR2HSV)
    for box in [(0, 0, shape[1], shape[0]), (3, 2, min(shape[1], 60), min(shape[0], 40)),
                (shape[1] // 2, shape[0] // 2, shape[1], shape[0])]:
        x0, y0, x1, y1 = box
        assert np.array_equal(roi.blurred_hsv(img, box, 3), full[y0:y1, x0:x1]), box


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


def test_frame_percentiles_are_numpys():
    # the adaptive thresholds' percentiles come from a histogram; they must be np.percentile's floats
    rng = np.random.default_rng(1)
    arrays = [np.array([7], np.uint8), np.full(50, 200, np.uint8), np.array([0, 255], np.uint8)]
    arrays += [rng.integers(lo, hi, n).astype(np.uint8) for n, lo, hi in [(4800, 0, 256), (1201, 30, 90), (33, 0, 3)]]
    for values in arrays:
        for q in (0, 5, 50, 90, 95, 100, 37.3):
            assert planes.percentile_u8(values, q) == float(np.percentile(values, q)), (values[:5], q)


def test_colour_planes_are_hue_value_chroma_and_saturation_masks(sign_frames):
    # a level of a colour plane is `hue in range & V >= v_min & chroma >= floor & S >= level`,
    # the masks' definition, pixel for pixel (on a sign frame: signs, sky, asphalt)
    img = sign_frames[3][0]
    params = ProposalParams()
    hsv = cv2.cvtColor(cv2.GaussianBlur(img, (3, 3), 0), cv2.COLOR_BGR2HSV)
    specs = proposals._color_specs(params, (1.0, 1.0))
    win = planes.window(hsv, (0, 0, 640, 480), specs, params.chroma_min)
    h, s, v = (hsv[:, :, i].astype(int) for i in range(3))
    chroma_ok = np.rint(s * v / 255.0) >= params.chroma_min
    for color, hues, s_min, v_min in specs:
        hue_ok = np.zeros(h.shape, bool)
        for lo, hi in hues:
            hue_ok |= (h >= lo) & (h <= hi)
        for level in (s_min, s_min + 50, 200):
            want = hue_ok & (v >= v_min) & chroma_ok & (s >= level)
            got = planes.level_mask(win.sat[color], level, None) > 0
            assert np.array_equal(got, want), (color, level)
            if level == s_min:
                assert want.sum() >= 100, color  # the frame holds both colours: the test is not vacuous


def test_each_colour_is_searched_around_its_own_coarse_blobs():
    # a no_left ring and a blue disc side by side: their windows overlap, but each colour's
    # full-resolution search runs in its own colour's windows; both signs keep their boxes
    from signlane.world.art import draw_sign

    img = np.full((240, 320, 3), (92, 94, 98), np.uint8)
    truth = {}
    for name, x in (("no_left", 100), ("left", 142)):
        sprite = draw_sign(name, 40, None, np.random.default_rng(0))
        a = sprite[..., 3:4].astype(np.float32) / 255.0
        part = img[80:120, x:x + 40].astype(np.float32)
        img[80:120, x:x + 40] = (a * sprite[..., :3] + (1 - a) * part + 0.5).astype(np.uint8)
        ys, xs = np.nonzero(sprite[..., 3] > 127)
        truth[name] = (x + int(xs.min()), 80 + int(ys.min()), int(np.ptp(xs)) + 1, int(np.ptp(ys)) + 1)
    fast, full = propose(img, ProposalParams()), propose(img, ProposalParams(regions=False))
    assert fast == full
    for name, color in (("no_left", "red"), ("left", "blue")):
        hits = [p for p in fast if proposals.box_iou(p.box, truth[name]) >= 0.7]
        assert [p.color for p in hits] == [color], (name, fast)


def test_frame_thresholds_from_the_half_copy_match_the_full_frames(sign_frames):
    # the adaptive thresholds are read off the half-size copy (the region search has it); they
    # must be what the blurred full-resolution frame's percentiles give, within a level, also
    # on dark and washed-out frames, where they adapt
    params = ProposalParams()
    for img, _ in sign_frames[::6]:
        for frame in (img, (img * 0.35).astype(np.uint8), (128 + img // 4).astype(np.uint8)):
            full = cv2.cvtColor(cv2.GaussianBlur(frame, (3, 3), 0), cv2.COLOR_BGR2HSV)[::8, ::8].reshape(-1, 3)
            ks = np.clip(np.percentile(full[:, 1], 95) / params.washed_s, 0.5, 1.0)
            kv = np.clip(np.percentile(full[:, 2], 90) / 200.0, 0.35, 1.0)
            want = proposals._color_specs(params, (ks, kv))
            got = proposals._color_specs(params, proposals._scales(frame, params))
            for (_, _, s_w, v_w), (_, _, s_g, v_g) in zip(want, got):
                assert abs(s_w - s_g) <= 1 and abs(v_w - v_g) <= 1, (want, got)
    dark = (sign_frames[0][0] * 0.35).astype(np.uint8)
    assert proposals._scales(dark, params)[1] < 0.6  # a dark frame does lower the V floors


def test_big_coarse_blobs_need_the_full_score():
    # small coarse blobs are kept at the loose score (ragged outlines at half size); a big one
    # (sky, wall, asphalt patch) must look like a sign as the full search requires
    blob = proposals._Blob
    size = proposals.COARSE_BIG
    blobs = [blob((0, 0, size - 1, size + 5), "blue", 0.3), blob((50, 0, size, size + 5), "blue", 0.3),
             blob((90, 0, size + 60, size), "red", 0.45)]
    kept = proposals._coarse_candidates(blobs, 0.4)
    assert [b.box for b in kept] == [blobs[0].box, blobs[2].box]
