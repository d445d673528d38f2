"""The end-to-end pilot: teacher recordings with perturbation, steering-consistent augmentation,
the model contract, and a smoke run recording -> training -> export -> parity -> a closed-loop
drive -> offline evaluation."""
import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from signlane.cli import main
from signlane.config import Config
from signlane.onnx_model import ModelError
from signlane.pilot import BRANCHED_CLASSES, PilotModel, desire_of, read_outputs
from signlane.sim.teacher import NoiseParams, SteeringNoise, TeacherRecorder
from signlane.types import Command, Frame, LaneEstimate, Perception


# --- teacher perturbation -------------------------------------------------------------------------
def test_noise_pulses_are_bounded_seeded_and_pause_at_junctions_and_stops():
    def run(seed, state="cruise"):
        noise = SteeringNoise(NoiseParams(scale=0.3), seed)
        return np.array([noise.step(i / 30, state, 5.0) for i in range(1800)])
    a, b = run(4), run(4)
    assert np.array_equal(a, b)  # seeded
    assert np.abs(a).max() <= 0.3 + 1e-9 and np.abs(a).max() > 0.1  # pulses happen, within the scale
    assert 0.05 < np.mean(a != 0) < 0.6  # the car is mostly driven by the teacher alone
    assert not run(4, "junction-left").any() and not run(4, "stopping").any()
    slow = SteeringNoise(NoiseParams(scale=0.3), 4)
    assert not any(slow.step(i / 30, "cruise", 0.2) for i in range(600))  # no pulse starts while crawling


class _FakeDriver:
    def step(self, telemetry, now=None):
        img = telemetry.image_bgr
        lane = LaneEstimate("fake", True, curvature=0.02)
        return Perception(Frame(img, now or 0.0), lane), Command(0.25, 0.4, "cruise")

    def close(self):
        pass


class _Recorder:
    def __init__(self):
        self.rows = []

    def write(self, frame_id, client, jpeg, tel, perception, sent, teacher=None, extra=None):
        self.rows.append((frame_id, sent, teacher, extra))


def test_the_recorded_label_is_the_teachers_clean_command_while_the_noisy_one_is_applied():
    from signlane.sim.protocol import Telemetry
    rec = _Recorder()
    drv = TeacherRecorder(_FakeDriver(), rec, SteeringNoise(NoiseParams(scale=0.3, gap_s=0.2), 1), every=2)
    tel = Telemetry(0.0, 0.0, 5.0, np.zeros((48, 64, 3), np.uint8), jpeg=b"\xff\xd8")
    applied = [drv.step(tel, now=i / 30)[1].steering for i in range(300)]
    assert len(rec.rows) == 150  # every 2nd frame
    assert all(t.steering == 0.25 for _, _, t, _ in rec.rows)  # the label: the teacher's own
    noisy = [(s.steering, e["noise"]) for _, s, _, e in rec.rows if e["noise"] != 0]
    assert noisy and all(abs(s - (0.25 + n)) < 1e-3 for s, n in noisy)  # applied = teacher + noise
    assert max(abs(a - 0.25) for a in applied) > 0.1


class _FakeStudent(_FakeDriver):
    """A driver with a pilot: it sends the student's steering; planner_command is the teacher's."""
    pilot = object()

    def __init__(self, student):
        self.student = student  # t -> the student's steering

    def step(self, telemetry, now=None):
        perception, teacher = super().step(telemetry, now)
        self.planner_command = teacher
        return perception, Command(self.student(now), teacher.throttle, teacher.state)


def test_dagger_the_student_steers_until_it_strays_then_the_teacher_for_hold_s_and_labels_all():
    from signlane.sim.protocol import Telemetry
    from signlane.sim.teacher import Takeover, TakeoverParams
    rec = _Recorder()
    # the student agrees with the teacher (0.25) but strays to -0.2 between 1.0 and 1.5 s
    drv = TeacherRecorder(_FakeStudent(lambda t: -0.2 if 1.0 <= t < 1.5 else 0.2), rec,
                          takeover=Takeover(TakeoverParams(margin=0.25, hold_s=1.0)))
    tel = Telemetry(0.0, 0.0, 5.0, np.zeros((48, 64, 3), np.uint8), jpeg=b"\xff\xd8")
    applied = {i: drv.step(tel, now=i / 30)[1].steering for i in range(120)}
    assert applied[10] == pytest.approx(0.2)  # the student's, within the margin
    assert applied[30] == pytest.approx(0.25) and applied[70] == pytest.approx(0.25)  # the teacher's from 1.0 s ...
    assert applied[73] == pytest.approx(0.25) and applied[74] == pytest.approx(0.2)  # ... until 1 s after its last stray frame (1.47 s)
    assert all(t.steering == 0.25 for _, _, t, _ in rec.rows)  # every label is the teacher's
    by = [e["steered_by"] for _, _, _, e in rec.rows]
    assert by.count("teacher") == 44 and rec.rows[10][3]["student"] == pytest.approx(0.2)
    assert drv.takeover.taken == 44 and drv.takeover.frames == 120


# --- augmentation keeps the label true ---------------------------------------------------------
def test_flip_negates_steering_and_swaps_desire_and_is_its_own_inverse():
    from signlane_train.pilot_data import flip_sample
    img = np.random.default_rng(0).integers(0, 255, (30, 40, 3), dtype=np.uint8)
    f, s, d = flip_sample(img, 0.3, "left")
    assert (s, d) == (-0.3, "right") and np.array_equal(f[:, 0], img[:, -1])
    back, s2, d2 = flip_sample(f, s, d)
    assert np.array_equal(back, img) and (s2, d2) == (0.3, "left")
    assert flip_sample(img, -0.1, "straight")[2] == "straight"


def test_flipped_frames_make_the_teacher_steer_the_mirrored_way():
    """The relabelling is what the teacher itself says of the mirrored frame (VIA's symmetric
    carriageway): the car placed off centre and askew, the teacher's steering on the frame and
    on its mirror image are opposite."""
    from signlane.drive.stack import DriveStack
    from signlane.sim.simulator import SimConfig, Simulator
    from signlane.world.maps import load_track
    from signlane.world.route import Pose
    from signlane_train.pilot_data import flip_sample
    sim = Simulator(load_track("loop_demo", "via"), SimConfig(image_lag_frames=0))
    p = sim.vehicle.pose
    right = np.array([np.sin(p.heading), -np.cos(p.heading)])
    steer = []
    for shift, yaw in ((0.5, 0.12), (-0.4, -0.08)):
        sim.vehicle.pose = Pose(p.x + shift * right[0], p.y + shift * right[1], p.heading - yaw)
        sim.observe()
        img = sim.last_image
        pair = []
        for frame in (img, flip_sample(img, 0.0, "straight")[0]):
            with DriveStack(Config.load(None, ["signs.enabled=false"])) as stack:
                pair.append(stack.drive(frame, 3.0, 0.0, 0.0)[1].steering)
        steer.append(pair)
    for s, mirrored in steer:
        assert abs(s) > 0.05  # off centre and askew: the teacher steers
        assert mirrored == pytest.approx(-s, abs=0.25 * abs(s) + 0.02)
    assert steer[0][0] * steer[1][0] < 0  # opposite placements, opposite steering


def test_a_shift_right_adds_right_steering_in_proportion():
    from signlane_train.pilot_data import shift_sample
    img = np.zeros((120, 160, 3), np.uint8)
    img[:, 70:90] = 255
    moved, s = shift_sample(img, 0.1, 10.0, gain=1.8)
    assert moved[:, 81:99].min() == 255 and moved[:, 70:79].max() == 0  # the content moved right
    assert s == pytest.approx(0.1 + 1.8 * np.arctan(10 / (80 / np.tan(np.radians(75.18) / 2))), abs=1e-6)
    assert shift_sample(img, 0.1, -10.0, gain=1.8)[1] < 0.1 < s


def test_a_lateral_move_shows_the_road_from_beside_the_line_and_steers_back():
    """The warp of the centred frame matches the simulator's frame rendered with the car moved
    sideways (below the horizon), and the label steers back the way the teacher does."""
    from signlane.drive.stack import DriveStack
    from signlane.sim.simulator import SimConfig, Simulator
    from signlane.world.maps import load_track
    from signlane.world.route import Pose
    from signlane_train.pilot_data import AugmentParams, flip_sample, lateral_sample
    sim = Simulator(load_track("loop_demo", "painted"), SimConfig(image_lag_frames=0))
    p = sim.vehicle.pose
    right = np.array([np.sin(p.heading), -np.cos(p.heading)])
    frames, teacher = {}, {}
    for d in (0.0, 0.5, -0.5):
        sim.vehicle.pose = Pose(p.x + d * right[0], p.y + d * right[1], p.heading)
        sim.observe()
        frames[d] = sim.last_image.copy()
        with DriveStack(Config.load(None, ["signs.enabled=false"])) as stack:
            teacher[d] = stack.drive(frames[d], 5.0, 0.0, 0.0)[1].steering
    gain = AugmentParams().lateral_gain
    road = slice(frames[0.0].shape[0] // 2, None)  # below the horizon (row 0.32 h for VIA's camera)
    for d in (0.5, -0.5):
        warped, label = lateral_sample(frames[0.0], 0.1, d, gain)
        moved = np.abs(warped[road].astype(int) - frames[d][road]).mean()
        unmoved = np.abs(frames[0.0][road].astype(int) - frames[d][road]).mean()
        assert moved < 0.3 * unmoved, (d, moved, unmoved)
        assert label == pytest.approx(0.1 - gain * d)
        assert np.sign(label - 0.1) == np.sign(teacher[d] - teacher[0.0]) != 0  # steer back toward the centre
        # mirrored, a move right is a move left
        a = flip_sample(warped, 0.0, "straight")[0]
        b = lateral_sample(flip_sample(frames[0.0], 0.0, "straight")[0], 0.0, -d, gain)[0]
        assert np.abs(a[road, 2:-2].astype(int) - b[road, 2:-2]).mean() < 1.0
    assert np.array_equal(lateral_sample(frames[0.0], 0.0, 0.5, gain)[0][:100], frames[0.0][:100])  # sky stays


def test_the_balancing_sampler_draws_rare_bends_as_often_as_straight_road():
    from signlane_train.pilot_data import steering_weights
    rng = np.random.default_rng(0)
    s = np.concatenate([rng.uniform(-0.04, 0.04, 900), rng.uniform(0.30, 0.34, 90), -rng.uniform(0.30, 0.34, 10)])
    assert np.allclose(steering_weights(s, 0.0), 1.0)
    w = steering_weights(s, 1.0)
    assert w.mean() == pytest.approx(1.0)
    straight, bends = w[:900].sum(), w[900:].sum()
    assert straight == pytest.approx(bends)  # one bin each, left and right bends together (a flip swaps them)
    half = steering_weights(s, 0.5)
    assert half[:900].sum() / half[900:].sum() == pytest.approx(3.0)  # sqrt(900 / 100)


def test_our_pilot_warms_up_then_anneals_its_rate_while_pilotnet_keeps_s3s_constant_rate():
    from types import SimpleNamespace

    import torch

    from signlane_train.common import one_cycle
    from signlane_train.pilot_task import PilotTask
    net = torch.nn.Linear(2, 1)
    opt = torch.optim.Adam(net.parameters(), lr=2e-3)
    sched = one_cycle(SimpleNamespace(trainer=SimpleNamespace(estimated_stepping_batches=100)), opt, 2e-3,
                      pct_start=0.2)["lr_scheduler"]["scheduler"]
    rates = []
    for _ in range(100):
        rates.append(opt.param_groups[0]["lr"])
        opt.step()
        sched.step()
    assert rates[0] < 2e-4 and max(rates) == pytest.approx(2e-3) and int(np.argmax(rates)) in range(18, 22)
    assert rates[-1] < 1e-5  # the last epoch trains at a rate near zero: it settles
    pilotnet = PilotTask(arch="pilotnet", lr=1e-4, input_size=(160, 120)).configure_optimizers()
    assert isinstance(pilotnet, torch.optim.Adam) and pilotnet.param_groups[0]["lr"] == 1e-4  # S3 as published
    with pytest.raises(ValueError, match="schedule 'cosine'"):
        PilotTask(arch="small", schedule="cosine")


def test_new_runs_train_leaky_relu_while_checkpoints_without_an_activation_keep_elu():
    import torch

    from signlane.pilot import PILOTNET_SPEC, SMALL_SPEC
    from signlane_train.pilot import DEFAULTS
    from signlane_train.pilot_data import cache_size
    from signlane_train.pilot_net import SmallPilot
    from signlane_train.pilot_task import PilotTask

    def acts(task):
        return {type(m) for m in task.net.modules() if isinstance(m, (torch.nn.ELU, torch.nn.LeakyReLU))}
    assert DEFAULTS["small"]["act"] == "leaky"
    assert acts(PilotTask(arch="small", input_size=(96, 72), act="leaky")) == {torch.nn.LeakyReLU}
    # a checkpoint saved before the choice has no "act" in its hyperparameters: ELU, as trained
    assert acts(PilotTask(arch="small", input_size=(96, 72))) == {torch.nn.ELU}
    with pytest.raises(ValueError, match="activation 'relu6'"):
        SmallPilot(act="relu6")
    # frames are augmented at the net's input size, never above the cache's
    assert cache_size(SMALL_SPEC) == (96, 72) and cache_size(PILOTNET_SPEC) == (160, 120)


def test_frames_load_alike_on_one_thread_or_many_and_an_unreadable_one_is_named(tmp_path):
    from signlane.pilot import PilotFrame
    from signlane_train.pilot_data import load_frames
    rng = np.random.default_rng(1)
    items = []
    for k in range(9):
        path = tmp_path / f"{k}.jpg"
        cv2.imwrite(str(path), rng.integers(0, 256, (48, 64, 3), np.uint8))
        items.append(PilotFrame(path, 0.0, "straight", 5.0, 0.0, "d", f"d/{k}"))
    one, many = load_frames(items, (32, 24), threads=1), load_frames(items, (32, 24), threads=4)
    assert one.shape == (9, 24, 32, 3) and np.array_equal(one, many)
    assert np.array_equal(one[4], cv2.resize(cv2.imread(str(items[4].image)), (32, 24), interpolation=cv2.INTER_AREA))
    (tmp_path / "5.jpg").write_bytes(b"not a jpeg")
    with pytest.raises(ValueError, match=r"5\.jpg: unreadable"):
        load_frames(items, (32, 24), threads=4)


def test_desire_follows_the_planned_exit_and_picks_the_branch():
    assert desire_of("junction-left") == "left" and desire_of("junction-right") == "right"
    assert desire_of("cruise") == desire_of("stopped") == desire_of("junction-straight") == "straight"
    row = np.array([-0.5, 0.1, 0.7, 4.2], np.float32)
    assert read_outputs(row, BRANCHED_CLASSES, "left").steering == pytest.approx(-0.5)
    assert read_outputs(row, BRANCHED_CLASSES, "right").steering == pytest.approx(0.7)
    assert read_outputs(row, BRANCHED_CLASSES, "straight").speed == pytest.approx(4.2)
    assert read_outputs(np.array([3.0]), ("steering",), "left").steering == 1.0  # clamped; one branch for all


# --- smoke: recording -> training -> export -> parity -> closed loop -> eval ---------------------------
@pytest.fixture(scope="module")
def pilot(tmp_path_factory):
    root = tmp_path_factory.mktemp("pilot")
    rec = root / "rec"
    assert main(["sim", "--track", "random", "--seed", "1001", "--record", str(rec), "--perturb", "0.3",
                 "--max-seconds", "5", "--no-signs"]) == 0
    from signlane_export.pilot import export_pilot
    from signlane_train.pilot import train_pilot
    report = train_pilot([rec], root / "run", arch="small", epochs=1, quiet=True, threads=1, val_fraction=0.5,
                         width=8)
    onnx_path = root / "pilot.onnx"
    exported = export_pilot(report["best_checkpoint"], onnx_path)
    return root, rec, report, onnx_path, exported


def test_sim_record_writes_the_drive_layout_with_teacher_desire_and_manifest(pilot):
    _, rec, *_ = pilot
    manifest = json.loads((rec / "manifest.json").read_text())
    assert manifest["drive"]["style"] == "via" and manifest["drive"]["track"] == "procedural-1001"
    n = manifest["counts"]["frames"]
    assert manifest["drive"]["perturb"]["scale"] == 0.3 and n in (150, 151)  # 5 s at 30 frames/s
    frames = [json.loads(line) for line in (rec / "drive.jsonl").read_text().splitlines()]
    assert len(frames) == n and all((rec / f["image"]).is_file() for f in frames)
    f = frames[-1]
    assert f["steering"] == f["teacher"]["steering"] and f["desire"] in ("left", "straight", "right")
    assert abs(f["command"]["steering"] - f["teacher"]["steering"] - f["noise"]) < 2e-4
    from signlane.sim.drive_record import read_recording
    assert len(read_recording(rec).frames) == n  # export-drive's reader takes it as it is


def test_frames_where_the_teacher_lost_the_lane_are_not_training_labels(pilot, tmp_path):
    import shutil
    from signlane.pilot import read_pilot_frames
    _, rec, *_ = pilot
    copy = tmp_path / "rec"
    shutil.copytree(rec, copy)
    frames = [json.loads(line) for line in (copy / "drive.jsonl").read_text().splitlines()]
    assert len(read_pilot_frames([rec])) == len(frames)  # the teacher saw the lane all along
    for f in frames[10:20]:
        f["teacher"]["state"] = "lost"
    (copy / "drive.jsonl").write_text("".join(json.dumps(f) + "\n" for f in frames))
    kept = read_pilot_frames([copy])
    assert len(kept) == len(frames) - 10
    assert {Path(it.image).name for it in kept}.isdisjoint(Path(f["image"]).name for f in frames[10:20])


def test_export_matches_torch_and_the_runtime_loads_it(pilot):
    root, rec, report, onnx_path, exported = pilot
    assert exported["parity_max_abs"] <= 1e-4 and exported["classes"] == list(BRANCHED_CLASSES)
    assert report["train_frames"] > 0 and np.isfinite(report["val_steering_mae"])
    model = PilotModel(onnx_path)
    assert model.spec.color == "HSV" and (model.spec.width, model.spec.height) == (96, 72)
    # the runtime's pre-processing is training's: the checkpoint on the same frame gives the same output
    import torch
    from signlane.pilot import preprocess_frames
    from signlane_train.pilot_task import PilotTask
    img = cv2.imread(str(next((rec / "images").iterdir())))
    task = PilotTask.load_from_checkpoint(report["best_checkpoint"], map_location="cpu").eval()
    with torch.no_grad():
        ref = task(torch.from_numpy(preprocess_frames([img], model.spec))).numpy()[0]
    assert np.allclose(model.predict([img])[0], ref, atol=1e-4)


def test_a_short_closed_loop_drive_steers_with_the_pilot(pilot):
    from signlane.sim.session import run_session
    from signlane.sim.simulator import SimConfig
    from signlane.world.maps import load_track
    root, _, _, onnx_path, _ = pilot
    cfg = Config.load(None, [f"pilot.model={onnx_path}", "signs.enabled=false", "pilot.junctions=pilot"])
    from signlane.sim.driver import Driver
    seen = []

    class Tap(Driver):
        def step(self, telemetry, now=None):
            perception, cmd = super().step(telemetry, now)
            seen.append((perception.timing_ms.get("pilot"), cmd.steering, self.pilot.last.steering))
            return perception, cmd
    from signlane.sim.simulator import Simulator, run_inprocess
    sim = Simulator(load_track("random", "via", 3), SimConfig(max_seconds=2.0))
    with Tap(cfg) as d:
        rep = run_inprocess(sim, d)
    assert len(seen) == 60 and all(ms is not None and ms > 0 for ms, _, _ in seen)
    assert all(s == p for _, s, p in seen)  # the steering sent is the pilot's
    assert rep["time_s"] == pytest.approx(2.0, abs=0.05)
    assert run_session(load_track("random", "via", 3), SimConfig(max_seconds=1.0), None, cfg,
                       show_progress=False)["time_s"] == pytest.approx(1.0, abs=0.05)


def test_at_a_planned_junction_the_planner_steers_by_default_or_the_pilot_told_the_exit_as_the_lost_turn():
    from signlane.pilot import PilotSteering

    class Model:
        def __init__(self):
            self.asked = []

        def step(self, frame, desire):
            from signlane.pilot import PilotOutput
            self.asked.append(desire)
            return PilotOutput({"left": -0.6, "straight": 0.05, "right": 0.6}[desire], 3.0)
    img = np.zeros((8, 8, 3), np.uint8)
    m = Model()
    assert PilotSteering(m).steer(img, "junction-left", -0.3) == -0.3 and m.asked == []
    assert PilotSteering(m).steer(img, "cruise", -0.3) == 0.05
    told = PilotSteering(m, "pilot")
    assert told.steer(img, "junction-left", -0.3) == -0.6 and told.steer(img, "junction-right", 0.2) == 0.6
    assert m.asked == ["straight", "left", "right"] and told.last.speed == 3.0
    # out of a planner-steered junction the lane follower finishes the exit: the pilot takes
    # over once the car is lined up with the exit lane (heading and offset small)
    from signlane.types import LaneEstimate
    steer = PilotSteering(m)
    turning = LaneEstimate("auto", True, offset=-0.3, heading=-0.5)
    straight = LaneEstimate("auto", True, offset=0.05, heading=0.03)
    assert steer.steer(img, "junction-right", 0.7, turning) == 0.7
    assert steer.steer(img, "cruise", 0.4, turning) == 0.4  # still askew: the planner's
    assert steer.steer(img, "cruise", 0.3, LaneEstimate("auto", False)) == 0.3  # lost: the planner's
    assert steer.steer(img, "cruise", 0.02, straight) == 0.05  # lined up: the pilot's from here on
    assert steer.steer(img, "cruise", 0.4, turning) == 0.05
    # with the lane lost the pilot steers, told the way the planner's course along the line it
    # last traced turns, where that is a turn (VIA seed 0's tight corner: the pilot, seeing only
    # verge, eased off to 0.05 and left the road; told "right" it turned in and found the lane)
    m.asked.clear()
    lost = PilotSteering(m)
    assert lost.steer(img, "lost", 0.8) == 0.6 and lost.steer(img, "lost", -0.35) == -0.6
    assert lost.steer(img, "lost", 0.2) == 0.05 and lost.steer(img, "cruise", 0.8, straight) == 0.05
    assert m.asked == ["right", "left", "straight", "straight"]
    assert desire_of("lost", 0.31) == "right" and desire_of("lost", -0.29) == "straight"


def test_with_a_pilot_a_lost_lane_slows_the_car_to_a_crawl_not_a_stand(pilot):
    from signlane.behaviour import Behaviour, BehaviourParams
    from signlane.config import Config
    from signlane.drive.stack import DriveStack
    from signlane.odometry import OdoPose
    from signlane.types import LaneEstimate
    onnx_path = pilot[3]
    # the planner's speed with no lane: a stand by default, lost_speed where it is given
    lost = LaneEstimate("auto", False)
    for lost_speed in (0.0, 1.0):
        b = Behaviour(BehaviourParams(max_speed=13.41, lost_speed=lost_speed))
        _, throttle, state = b.step(0.0, OdoPose(0.0, 0.0), 0.0, 0.5, lost, None)
        assert state == "lost" and throttle == pytest.approx(lost_speed / 13.41)
    # the drive stack gives it only to a planner whose car a pilot steers
    with_pilot = DriveStack(Config.load(None, [f"pilot.model={onnx_path}", "signs.enabled=false"]))
    alone = DriveStack(Config.load(None, ["signs.enabled=false"]))
    assert with_pilot.behaviour.p.lost_speed == 1.0 and alone.behaviour.p.lost_speed == 0.0
    with pytest.raises(ValueError, match="pilot.lost_speed"):
        Config.load(None, ["pilot.lost_speed=20", "drive.max_speed=13.41"])


def test_eval_pilot_scores_models_side_by_side_and_draws(pilot, tmp_path, capsys):
    root, rec, _, onnx_path, _ = pilot
    assert main(["eval", "pilot", str(rec), "--model", str(onnx_path), "--model", str(onnx_path),
                 "--out", str(tmp_path), "--json", str(tmp_path / "s.json")]) == 0
    s = json.loads((tmp_path / "s.json").read_text())
    n = json.loads((rec / "manifest.json").read_text())["counts"]["frames"]
    assert s["frames"] == n and list(s["models"]) == ["pilot", "pilot_2"]
    a, b = s["models"]["pilot"], s["models"]["pilot_2"]
    assert a == b and 0 < a["all"]["mae"] <= a["all"]["rmse"] and a["all"]["frames"] == n
    assert sum(a[k]["frames"] for k in a if k.split()[0] in ("straight", "bend", "turn")) == n
    for name in ("steering.png", "disagree_pilot.png", "disagree_pilot_2.png"):
        img = cv2.imread(str(tmp_path / name))
        assert img is not None and img.shape[0] > 100
    assert "pilot MAE / RMSE" in capsys.readouterr().out


# --- the contract -----------------------------------------------------------------------------------
def test_the_contract_refuses_lane_and_sign_models_as_pilots_and_a_pilot_as_either(pilot, capsys):
    from signlane.lanes.seg_model import DEFAULT_MODEL as LANES, LaneSegModel
    from signlane.signs.classifier import DEFAULT_MODEL as SIGNS, SignClassifier
    _, _, _, onnx_path, _ = pilot
    for other in (LANES, SIGNS):
        with pytest.raises(ModelError, match="expected 'pilot'"):
            PilotModel(other)
    with pytest.raises(ModelError, match="is 'pilot', expected 'lane-segmentation'"):
        LaneSegModel(onnx_path)
    with pytest.raises(ModelError, match="is 'pilot'"):
        SignClassifier(onnx_path)
    assert main(["sim", "--track", "random", "--record", str(onnx_path.parent / "x"), "--max-seconds", "1",
                 "--set", f"pilot.model={LANES}"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert "lanes.onnx" in err[-1] and "expected 'pilot'" in err[-1]
    with pytest.raises(ValueError, match="pilot.junctions"):
        Config.load(None, ["pilot.junctions=sometimes"])
