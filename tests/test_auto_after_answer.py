"""On a kerbed road `auto`'s lane is the carriageway, and its look for lane paint (the paint
method, which costs about as much as the carriageway again) is made after the frame's answer:
the frame's lane never waits on it. The look is made on the frame it was put off from, by
`LaneMethod.settle()` (the drive stack's `answered()`), or else first thing on the next frame,
so a stream reads the same either way."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from signlane import lanes
from signlane.camera import via_camera
from signlane.config import Config
from signlane.drive.stack import DriveStack
from signlane.lanes import auto as auto_module
from signlane.world.sampling import DriveSampler, SamplerConfig


def _drive(style: str, seed: int, n: int) -> list[np.ndarray]:
    """n consecutive 320x240 frames of a drive in a style's default look."""
    sampler = DriveSampler(seed, SamplerConfig(320, 240, style=style, effects="normal", randomise=False))
    return [sampler.sample(i).image for i in range(n)]


@pytest.fixture(scope="module")
def via_frames():
    """40 frames of a drive on VIA's kerbed carriageway."""
    return _drive("via", 7, 40)


@pytest.fixture(scope="module")
def painted_frames():
    """60 frames of a drive on a painted two-lane road (its dashed centre line)."""
    return _drive("painted", 3, 60)


def _counting(monkeypatch, name: str) -> list[int]:
    """Count the calls `auto` makes to one of its parts (its module's `name`)."""
    calls = []
    real = getattr(auto_module, name)
    monkeypatch.setattr(auto_module, name, lambda *a, **k: calls.append(1) or real(*a, **k))
    return calls


def _counting_paint(monkeypatch):
    return _counting(monkeypatch, "_paint")


def test_the_kerbed_roads_look_for_paint_waits_for_the_answer(via_frames, monkeypatch):
    calls = _counting_paint(monkeypatch)
    lane = lanes.get("auto", camera=via_camera(320, 240))
    est = lane(via_frames[0])
    assert calls == [1]  # nothing known of the road yet: the first frame looks at once
    assert est.found and est.basis == "edges" and lane.state.pending is None
    deferred = 0
    for img in via_frames[1:]:
        calls.clear()
        est = lane(img)
        assert calls == [] and est.basis == "edges"  # the frame's lane did not wait on the paint method
        if lane.state.pending is not None:
            deferred += 1
            lane.settle()  # the answer is out: now it looks
            assert calls == [1] and lane.state.pending is None
    assert deferred == 4  # a road long without lanes is looked at on one frame in eight: 8, 16, 24, 32


def test_a_stream_reads_the_same_settled_after_each_answer_or_on_the_next_frame(via_frames):
    cam = via_camera(320, 240)
    a, b = lanes.get("auto", camera=cam), lanes.get("auto", camera=cam)
    for img in via_frames:
        ea, eb = a(img), b(img)
        a.settle()  # b settles inside its next call
        assert ea.offset == eb.offset and ea.basis == eb.basis and ea.found == eb.found
    b.settle()
    assert a.state.lanes_seen == b.state.lanes_seen and a.state.since_check == b.state.since_check


def test_the_drive_stack_settles_the_lane_method_when_its_answer_is_out(via_frames, monkeypatch):
    calls = _counting_paint(monkeypatch)
    stack = DriveStack(Config.load(None, ["signs.enabled=false"]))
    looked = []
    for i, img in enumerate(via_frames[:17]):
        stack.drive(cv2.resize(img, (640, 480)), 3.0, 0.0, i / 30)
        calls.clear()
        stack.answered()
        assert stack.perception.lane.state.pending is None
        looked += [i] * len(calls)  # the look put off by this frame, made now
    assert looked == [8, 16]  # (frame 0 looked at once: nothing was known of the road)
    assert np.isfinite(stack.perception.lane.state.lanes_seen)


def test_the_lanes_are_those_of_the_look_made_at_once_with_tracks_forgotten_between(monkeypatch):
    """On a drive whose share of lane sightings wanders from 0 to above the bar (random looks:
    paint-like shadows), with the tracks forgotten after every eleventh frame (a junction crossed):
    put off or not, the same lanes and the same state."""
    sampler = DriveSampler(4, SamplerConfig(320, 240, style="via", effects="normal"))
    frames = [sampler.sample(i).image for i in range(130)]
    calls = _counting_paint(monkeypatch)
    cam = via_camera(320, 240)
    late, now = lanes.get("auto", camera=cam), lanes.get("auto", camera=cam)
    deferred, seen = 0, []
    for i, img in enumerate(frames):
        a = late(img)
        deferred += late.state.pending is not None
        b = now(img)
        now.settle()  # the look made during the frame, before anything else: as it was
        if i % 11 == 10:
            late.state = late.state.forget_tracks()
            now.state = now.state.forget_tracks()
        late.settle()
        assert (a.found, a.basis, a.offset, a.lane_width_m) == (b.found, b.basis, b.offset, b.lane_width_m), i
        assert late.state.lanes_seen == now.state.lanes_seen and (late.state.paint is None) == (now.state.paint is None)
        seen.append(now.state.lanes_seen)
    assert deferred >= 20 and max(seen) > 0.7  # both paths ran: put off, and at once near the bar
    assert calls  # the paint method did run


def test_a_two_lane_roads_carriageway_waits_for_the_answer_where_the_paint_is_found(painted_frames, monkeypatch):
    """With `edges_after_answer`, a frame of a road known to have a centre line whose paint is
    found is answered from the paint alone; its carriageway scan is made by settle(). The lanes,
    and the road's state once settled, are those of the scan made at once."""
    calls = _counting(monkeypatch, "carriageway")
    cam = via_camera(320, 240)
    late, now = lanes.get("auto", camera=cam, edges_after_answer=True), lanes.get("auto", camera=cam)
    waited = 0
    for i, img in enumerate(painted_frames):
        calls.clear()
        a = late(img)
        if late.state.pending is not None:
            waited += 1
            assert calls == [] and a.basis == "paint" and a.found  # answered without the scan
            late.settle()
            assert calls == [1] and late.state.pending is None
        b = now(img)
        assert (a.found, a.basis, a.offset, a.heading, a.lane_width_m) == (b.found, b.basis, b.offset, b.heading,
                                                                            b.lane_width_m), i
        assert (late.state.road.centre_paint, late.state.road.width_m) == (now.state.road.centre_paint,
                                                                           now.state.road.width_m), i
        assert np.array_equal(late.state.road.scan.y, now.state.road.scan.y)
    assert now.state.two_lane and waited >= 50  # all but the first frames, which learn the road has a centre line


def test_only_a_caller_that_answers_puts_the_carriageway_off(painted_frames):
    """The drive stack (which settles after each answer) sets `edges_after_answer`; infer's
    perception, whose every frame's drivable mask is its own, does not."""
    from signlane.drive.perception import PerceptionStack
    stack = DriveStack(Config.load(None, ["signs.enabled=false"]))
    stack.drive(cv2.resize(painted_frames[0], (640, 480)), 3.0, 0.0, 0.0)
    assert stack.perception.lane.params.edges_after_answer
    infer_like = PerceptionStack(Config.load(None, ["signs.enabled=false"]), junctions=False)
    infer_like.lanes_on(painted_frames[0])
    assert not infer_like.lane.params.edges_after_answer


def test_a_road_without_a_centre_line_runs_one_method_a_frame_with_the_drive_stacks_setting(monkeypatch):
    """With `edges_after_answer`, a road without a centre line runs, per frame, the method the
    frames before chose (read as lanes: the paint; kerbed: the carriageway), the other after its
    answer. On a drive whose share of lane sightings wanders over the bar (random looks), the
    lanes are those of both methods run at once but where the decision switches a frame later."""
    sampler = DriveSampler(4, SamplerConfig(320, 240, style="via", effects="normal"))
    frames = [sampler.sample(i).image for i in range(130)]
    calls = []
    for name in ("carriageway", "_paint"):
        real = getattr(auto_module, name)
        monkeypatch.setattr(auto_module, name, lambda *a, real=real, name=name, **k: calls.append(name) or real(*a, **k))
    cam = via_camera(320, 240)
    late, now = lanes.get("auto", camera=cam, edges_after_answer=True), lanes.get("auto", camera=cam)
    both = same = read_as_lanes = 0
    for img in frames:
        calls.clear()
        a = late(img)
        both += len(set(calls)) == 2
        pending = late.state.pending
        if a.basis == "paint":  # read as lanes: answered from the paint, its carriageway put off
            read_as_lanes += 1
            assert calls == ["_paint"] and pending is not None and pending.look is not None
        late.settle()
        b = now(img)
        now.settle()
        same += (a.found, a.basis, a.offset) == (b.found, b.basis, b.offset)
    assert both <= 2  # the first frame (nothing known) and frames read as lanes whose paint is not found
    assert read_as_lanes >= 3 and same >= 125  # both readings occur; they differ only at the switches


def test_a_kerbed_frames_drivable_mask_is_made_after_its_answer(via_frames, monkeypatch):
    """With `edges_after_answer` the carriageway's drivable mask (an unwarp of its bird's-eye
    road) is made by settle(): a frame shows the frame before's; once settled, the mask is the
    one the method makes at once."""
    from signlane.lanes import road_edges
    unwarps = []
    real = road_edges.drivable_mask
    monkeypatch.setattr(auto_module, "drivable_mask", lambda *a: unwarps.append(1) or real(*a))
    cam = via_camera(320, 240)
    late, now = lanes.get("auto", camera=cam, edges_after_answer=True), lanes.get("auto", camera=cam)
    before = None
    for img in via_frames[:12]:
        unwarps.clear()
        a = late(img)
        assert unwarps == []  # not on the frame's path
        assert (a.drivable_mask is None and before is None) or np.array_equal(a.drivable_mask, before)
        late.settle()
        assert unwarps == [1]
        b = now(img)
        now.settle()
        assert b.found and np.array_equal(late.state.drivable, b.drivable_mask) and b.drivable_mask.any()
        before = late.state.drivable


def test_a_paint_frames_debug_mask_is_made_after_its_answer(painted_frames):
    """With `edges_after_answer` the paint method's debug mask (its kept lines' pixels, warped to
    the frame) is made by settle(): a frame answered from the paint shows the frame before's,
    which is the mask the method makes at once on that frame."""
    cam = via_camera(320, 240)
    late, now = lanes.get("auto", camera=cam, edges_after_answer=True), lanes.get("auto", camera=cam)
    before, shown = None, 0
    for img in painted_frames[:20]:
        a = late(img)
        b = now(img)
        now.settle()
        if a.basis == "paint" and before is not None:
            assert np.array_equal(a.debug_mask, before)
            shown += 1
        late.settle()
        assert np.array_equal(late.state.debug, b.debug_mask) and b.debug_mask.any()
        before = b.debug_mask
    assert shown >= 15
