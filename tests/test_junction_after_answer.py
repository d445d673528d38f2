"""The drive stack's painted-road junction detector runs once a frame's command is out; the next
frame reads its view with the openings moved nearer by the metres the car drove since
(drive/perception.py). The kerbed road's view, read from the frame's own scan, is not put off."""
from __future__ import annotations

import pytest

from signlane.config import Config
from signlane.drive.stack import DriveStack
from signlane.junction import JunctionDetector, JunctionView, Opening, moved_on
from signlane.world.sampling import DriveSampler, SamplerConfig


def test_moved_on_brings_the_openings_nearer_by_the_metres_driven():
    view = JunctionView(Opening(10.0, 17.0, True), None, True, straight_dead=False)
    near = moved_on(view, 0.25)
    assert (near.left.near_m, near.left.far_m, near.left.closed) == (9.75, 16.75, True)
    assert near.right is None and near.straight is True and near.straight_dead is False
    assert moved_on(view, 0.0) is view


def test_a_painted_frame_reads_the_frame_befores_junction_view_moved_on(monkeypatch):
    sampler = DriveSampler(3, SamplerConfig(640, 480, style="painted", effects="normal", randomise=False,
                                            junctions=1.0))
    frames = [sampler.sample(i).image for i in range(36)]
    detected, read, in_step = [], [], [False]
    real_detect = JunctionDetector.detect

    def detect(self, *a, **k):
        assert not in_step[0]  # never on the steering path
        view = real_detect(self, *a, **k)
        detected.append(view)
        return view
    monkeypatch.setattr(JunctionDetector, "detect", detect)
    stack = DriveStack(Config.load(None, ["signs.enabled=false"]))
    real_step = stack.behaviour.step

    def step(t, pose, odo_m, speed, lane, view, two_lane=True):
        read.append((view, odo_m, two_lane))
        return real_step(t, pose, odo_m, speed, lane, view, two_lane)
    monkeypatch.setattr(stack.behaviour, "step", step)
    for i, img in enumerate(frames):
        in_step[0] = True
        stack.drive(img, 6.0, 0.0, i / 30)
        in_step[0] = False
        stack.answered()
    assert all(two_lane for _, _, two_lane in read) and len(detected) == len(frames)
    assert read[0][0].left is None and read[0][0].right is None  # nothing seen before the first frame
    openings = 0
    for (view, odo, _), (_, odo_before, _), before in zip(read[1:], read, detected):
        expected = moved_on(before, odo - odo_before)
        assert odo - odo_before == pytest.approx(6.0 / 30)
        assert (view.left, view.right) == (expected.left, expected.right)
        openings += view.left is not None or view.right is not None
    assert openings >= 3  # the frames stand before junctions: side roads were seen, moved on
