"""The drive stack's sign search on the rows where sign faces can stand (signs/face_rows.py):
every sign a driving camera sees whole lies in them, on procedural tracks and on a map in VIA's
format (via_town); a sign in them keeps its box; and a camera setting that does not match the
frames gives the band up instead of hiding the signs."""
from __future__ import annotations

import logging
import numpy as np
import pytest

from signlane.camera import Camera, via_camera
from signlane.config import SignsConfig
from signlane.signs.face_rows import RowBand, face_rows
from signlane.signs.proposals import propose
from signlane.signs.stage import SignStage
from signlane.world.art import draw_sign
from signlane.world.maps import load_track
from signlane.world.sampling import DriveSampler, SamplerConfig
from signlane.world.track import SIGN_FACE_M, SIGN_HEIGHT_M

from tests.test_proposals import _background, _paste

LOW, HIGH = SIGN_HEIGHT_M - SIGN_FACE_M / 2, SIGN_HEIGHT_M + SIGN_FACE_M / 2


def _whole_signs(track, style: str, camera: Camera, frames: int = 200, seed: int = 0):
    """Boxes (x, y, w, h) of the signs seen whole and unhidden along a drive of the track."""
    sampler = DriveSampler(seed, SamplerConfig(width=camera.width, height=camera.height, style=style,
                                               effects="clean", randomise=False), fps=20.0, track=track,
                           camera=camera)
    for i in range(0, 3 * frames, 3):
        for s in sampler.sample(i).truth.signs:
            if s.truncated == 0 and s.occluded < 0.5 and s.box[3] >= 8:
                yield s.box


def test_the_band_of_vias_camera_is_the_horizon_and_a_third_of_the_frame():
    top, bottom = face_rows(via_camera(640, 480), 4.0, LOW, HIGH)
    horizon = 240 - via_camera(640, 480).focal_px * np.tan(np.radians(11.8))  # row 153
    assert top < horizon < bottom
    assert 100 <= top <= 130 and 270 <= bottom <= 310  # the road below and most of the sky above are left out
    assert (bottom - top) / 480 < 0.4
    assert face_rows(via_camera(640, 480), 0.0, LOW, HIGH) is None  # 0: every row
    near = face_rows(via_camera(640, 480), 2.0, LOW, HIGH)
    assert near[0] < top and near[1] > bottom  # nearer faces reach further from the horizon


@pytest.mark.parametrize("style,seed", [("via", 0), ("via", 1), ("painted", 1), ("painted", 3)])
def test_every_sign_seen_whole_lies_in_the_band(style, seed):
    camera = via_camera(640, 480)  # the simulator's camera in both styles
    top, bottom = face_rows(camera, 4.0, LOW, HIGH)
    boxes = list(_whole_signs(load_track("random", style, seed), style, camera))
    assert len(boxes) >= 8
    assert [b for b in boxes if b[1] < top or b[1] + b[3] > bottom] == []


def test_every_sign_of_a_map_in_vias_format_lies_in_the_band():
    """via_town: signs where VIA's editor puts them, 1.6 to 4.5 m beside the asphalt, some
    facing the car across a junction (VIA's own default maps in ../shared have no signs)."""
    camera = via_camera(640, 480)
    top, bottom = face_rows(camera, 4.0, LOW, HIGH)
    boxes = list(_whole_signs(load_track("via_town", "via", 0), "via", camera))
    assert len(boxes) >= 20
    assert [b for b in boxes if b[1] < top or b[1] + b[3] > bottom] == []


def test_a_sign_in_the_band_keeps_its_box_one_below_it_is_not_searched():
    img = np.ascontiguousarray(np.vstack([_background(240, 640, 1), _background(240, 640, 2)]))
    rng = np.random.default_rng(0)
    high = _paste(img, draw_sign("stop", 40, None, rng), 200, 150)
    low = _paste(img, draw_sign("no_left", 40, None, rng), 420, 380)
    rows = face_rows(via_camera(640, 480), 4.0, LOW, HIGH)
    everywhere, banded = propose(img), propose(img, rows=rows)
    assert len(everywhere) == 2
    assert [p.box for p in banded] == [p.box for p in everywhere if p.box[1] < 300]
    assert abs(banded[0].box[0] - high[0]) <= 3 and not any(abs(p.box[1] - low[1]) < 20 for p in banded)


def test_a_camera_that_does_not_match_gives_the_band_up_and_the_signs_are_found(caplog):
    """Frames from a camera 1.3 m up, as a small car's, read with VIA's camera's band: the faces
    reach above the band. The band is checked on one frame in 15 and given up on the second
    check that reads a sign outside it; a sign is then confirmed."""
    track = load_track("via_town", "via", 0)
    low_camera = Camera(640, 480, hfov_deg=90.0, height_m=1.3, pitch_deg=10.0)
    sampler = DriveSampler(0, SamplerConfig(width=640, height=480, style="via", effects="clean",
                                            randomise=False), fps=20.0, track=track, camera=low_camera)
    frames = [sampler.sample(i) for i in range(0, 600, 3)]
    frames = [f for f in frames if any(s.truncated == 0 and s.box[3] >= 16 for s in f.truth.signs)]
    assert len(frames) >= 40
    stage = SignStage(SignsConfig())
    rows = face_rows(via_camera(640, 480), 4.0, LOW, HIGH)
    stage.band = RowBand((640, 480), rows)
    # the nearer (larger) faces reach above the band: their lower part alone would be searched
    assert sum(s.box[1] < rows[0] for f in frames for s in f.truth.signs if s.truncated == 0) >= 8
    confirmed_at = None
    with caplog.at_level(logging.WARNING, logger="signlane.signs.face_rows"):
        for k, f in enumerate(frames):
            stage.step(f.image)
            if stage.band.given_up and confirmed_at is None and stage.confirmed:
                confirmed_at = k
    assert stage.band.given_up and stage.band.outside == 2
    assert confirmed_at is not None
    assert "camera.* may not match" in caplog.text


def test_a_check_frame_is_answered_from_the_band_and_checked_after_its_answer():
    """The frame due for the whole-row check gets the band's signs like any other (its cost on
    the steering path is the band's); settle(), called once the command is out, searches every
    row and counts the sign the classifier reads above the band."""
    track = load_track("via_town", "via", 0)
    low_camera = Camera(640, 480, hfov_deg=90.0, height_m=1.3, pitch_deg=10.0)
    sampler = DriveSampler(0, SamplerConfig(width=640, height=480, style="via", effects="clean",
                                            randomise=False), fps=20.0, track=track, camera=low_camera)
    rows = face_rows(via_camera(640, 480), 4.0, LOW, HIGH)
    frame = next(f for f in (sampler.sample(i) for i in range(0, 600, 3))
                 if any(s.truncated == 0 and s.box[1] < rows[0] - 10 and s.box[3] >= 30 for s in f.truth.signs))
    stage = SignStage(SignsConfig())
    stage.band = RowBand((640, 480), rows, check_every=1)
    found, _ = stage.step(frame.image)
    assert stage.band.due and stage.band.outside == 0  # not yet checked: the answer comes first
    assert all(rows[0] <= d.box[1] and d.box[1] + d.box[3] <= rows[1] for d in found)
    stage.settle()
    assert stage.band.outside == 1
    stage.settle()  # once per due frame
    assert stage.band.outside == 1


def _drive_with_signs(n: int):
    """n consecutive 640x480 frames (30 frames/s) of a drive on via_town through VIA's camera, from
    the first with a sign seen whole."""
    sampler = DriveSampler(0, SamplerConfig(width=640, height=480, style="via", effects="clean", randomise=False),
                           fps=30.0, track=load_track("via_town", "via", 0), camera=via_camera(640, 480))
    start = next(i for i in range(0, 900, 5)
                 if any(s.truncated == 0 and s.box[3] >= 20 for s in sampler.sample(i).truth.signs))
    return [sampler.sample(i).image for i in range(start, start + n)]


def test_proposals_near_a_frames_own_proposals_are_its_proposals():
    """The tracked search around a frame's proposals finds those proposals again, box for box."""
    from signlane.signs.proposals import propose_near
    frames = _drive_with_signs(30)
    compared = 0
    for img in frames[::3]:
        found = propose(img)
        compared += len(found)
        assert [(p.box, p.color) for p in propose_near(img, found)] == [(p.box, p.color) for p in found]
    assert compared >= 10
    assert propose_near(frames[0], []) == []


def test_a_drive_stack_searches_the_band_whole_one_frame_in_three_and_tracks_between(monkeypatch):
    """With a band, the stage searches the band whole on one frame in `search_every` and only
    around the last frame's proposals between: on a drive past signs, the same labels frame by
    frame as whole searches of every frame (the signs move a few pixels a frame), at a fraction
    of the whole searches."""
    from signlane.signs import proposals as proposals_module
    frames = _drive_with_signs(45)
    rows = face_rows(via_camera(640, 480), 4.0, LOW, HIGH)
    whole = []
    real = proposals_module.propose
    monkeypatch.setattr(proposals_module, "propose", lambda *a, **k: whole.append(1) or real(*a, **k))
    labels = {}
    for every in (1, 3):
        stage = SignStage(SignsConfig(search_every=every))
        stage.band = RowBand((640, 480), rows, check_every=1000)
        whole.clear()
        labels[every] = [sorted(d.label for d in stage.step(img)[0] if d.label != "unknown") for img in frames]
        assert len(whole) == (45 if every == 1 else 15)
    assert sum(bool(x) for x in labels[1]) >= 20  # signs read on most frames
    assert sum(a == b for a, b in zip(labels[1], labels[3])) >= 43
