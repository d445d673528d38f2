"""Nothing silent, nothing unbounded: each failure mode a user can provoke gets one clear line
and a safe outcome (the drive server, infer, sim, config, media, training, dataset resume).

New names are imported inside the tests, so each test fails on its own when its fix is missing."""
import json
import logging
import socket
import struct
import threading
import time
import zlib
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest
from websockets.sync.client import connect

from gen_helpers import generate_lanes_killed_at
from signlane.cli import main
from signlane.config import Config
from signlane.sim.protocol import SAFE_COMMAND, encode_jpeg, encode_telemetry
from signlane.sim.server import DriveServer, ServerOptions
from signlane.types import Command, LaneEstimate, Perception
from signlane.world.sampling import FrameSampler, SamplerConfig

SAFE = json.loads(SAFE_COMMAND)


@pytest.fixture(scope="module")
def road():
    smp = FrameSampler(11, SamplerConfig(320, 240, effects="clean", randomise=False, lateral_m=0.1, heading_deg=1))
    return [smp.sample(i).image for i in range(3)]


def tel(image_or_jpeg, i: int = 0) -> str:
    jpeg = image_or_jpeg if isinstance(image_or_jpeg, bytes) else encode_jpeg(image_or_jpeg)
    return encode_telemetry(0.0, 0.3, 5.0, jpeg, time=0.05 * i)


def ask(ws, message) -> dict:
    ws.send(message)
    return json.loads(ws.recv(timeout=30))


def warnings_of(caplog, words: str) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING and words in r.getMessage()]


def one_error_line(err: str, command: str) -> str:
    lines = [line for line in err.strip().splitlines() if line.strip() and "%|" not in line]
    assert len(lines) == 1, lines
    assert lines[0].startswith(f"signlane {command}: error: ") and "Traceback" not in err, err
    return lines[0]


# ---------------------------------------------------------------------- 1. the sign stage fails
def test_a_failing_sign_thread_stops_the_car_logs_once_and_keeps_trying(road, caplog, monkeypatch):
    from signlane.signs.stage import SignStage
    real_step = SignStage.step
    state = {"broken": False}
    failed, recovered = threading.Event(), threading.Event()

    def step(self, image):
        if state["broken"]:
            failed.set()
            raise RuntimeError("output has 3 values for 7 classes")
        out = real_step(self, image)
        recovered.set()
        return out
    monkeypatch.setattr(SignStage, "step", step)
    caplog.set_level(logging.INFO, logger="signlane.drive")
    with DriveServer(Config(), ServerOptions(port=0, sync_signs=False)) as srv:  # signs in their own thread
        with connect(srv.url) as ws:
            assert ask(ws, tel(road[0], 0))["throttle"] > 0  # driving
            state["broken"] = True
            ask(ws, tel(road[1], 1))  # the sign thread takes this frame and fails
            assert failed.wait(20)
            answers = [ask(ws, tel(road[k % 3], k)) for k in range(2, 8)]
            assert answers == [SAFE] * 6  # never drives on without the signs it was asked to obey
            state["broken"] = False
            recovered.clear()
            ask(ws, tel(road[0], 8))  # the stage is tried again on new frames ...
            assert recovered.wait(20)
            assert ask(ws, tel(road[1], 9))["throttle"] > 0  # ... and driving resumes once it works
    lines = warnings_of(caplog, "sign stage failed")
    assert lines[0] == ("client 1: sign stage failed: RuntimeError: output has 3 values for 7 classes; "
                        "answered with the safe command")
    assert len(lines) == 2 and "(repeated" in lines[1]  # once, then a count when the client left
    assert srv.totals["bad"] >= 6


def test_signs_beside_the_lane_path_search_a_frame_only_once_its_command_is_out(road, monkeypatch):
    """The worker's search would compete with the steering path for the interpreter: it gets each
    frame after `answered()`, or with the next frame from a caller that never says so."""
    from signlane.drive.stack import DriveStack
    from signlane.signs.stage import SignStage
    real_step, started = SignStage.step, []
    ran = threading.Event()

    def step(self, image):
        started.append(int(image[0, 0, 0]))
        ran.set()
        return real_step(self, image)
    monkeypatch.setattr(SignStage, "step", step)
    frames = [road[k].copy() for k in range(3)]
    for k, f in enumerate(frames):
        f[0, 0] = k  # which frame the worker searched
    with DriveStack(Config(), sync_signs=False) as stack:
        stack.drive(frames[0], 3.0, 0.0, 0.0)
        assert not ran.wait(0.5) and started == []  # held back while the command is not out
        stack.answered()
        assert ran.wait(10) and started == [0]
        ran.clear()
        stack.drive(frames[1], 3.0, 0.0, 0.1)  # never answered: goes with the next frame
        assert not ran.wait(0.5)
        stack.drive(frames[2], 3.0, 0.0, 0.2)
        assert ran.wait(10) and started == [0, 1]


def test_a_sign_model_whose_graph_breaks_its_contract_is_refused_at_startup(tmp_path):
    from signlane.onnx_model import ModelError
    bad = sign_model(tmp_path / "identity.onnx", identity=True)
    cfg = Config.load(None, [f"signs.model={bad}"])
    srv = DriveServer(cfg, ServerOptions(port=0))
    try:
        with pytest.raises(ModelError, match=r"identity.onnx: graph output is \(2, 3, 32, 32\)"):
            srv.start()
    finally:
        srv.close()


# ---------------------------------------------------------------------- 4. graphs vs metadata
def sign_model(path: Path, classes=None, n_out=7, identity=False, dtype=None, size=32, task=None,
               spec_size=32) -> Path:
    """A tiny ONNX graph with signlane metadata: flatten -> matmul to `n_out` logits (or the
    identity), input `dtype` (float32 by default)."""
    onnx = pytest.importorskip("onnx")
    from onnx import TensorProto, helper, numpy_helper
    from signlane.onnx_model import make_metadata
    from signlane.signs.classifier import DEFAULT_SPEC, TASK
    from signlane.world.art import SIGN_CLASSES
    elem = dtype or TensorProto.FLOAT
    x = helper.make_tensor_value_info("input", elem, ["batch", 3, size, size])
    if identity:
        nodes, inits = [helper.make_node("Identity", ["input"], ["output"])], []
        y = helper.make_tensor_value_info("output", elem, ["batch", 3, size, size])
    else:
        w = np.full((3 * size * size, n_out), 1e-3, np.float64 if elem == TensorProto.DOUBLE else np.float32)
        inits = [numpy_helper.from_array(w, "w")]
        nodes = [helper.make_node("Flatten", ["input"], ["flat"]),
                 helper.make_node("MatMul", ["flat", "w"], ["output"])]
        y = helper.make_tensor_value_info("output", elem, ["batch", n_out])
    model = helper.make_model(helper.make_graph(nodes, "g", [x], [y], inits),
                              opset_imports=[helper.make_opsetid("", 17)])
    model.ir_version = 8
    spec = replace(DEFAULT_SPEC, width=spec_size, height=spec_size)
    meta = make_metadata(task or TASK, list(classes or SIGN_CLASSES), spec, "test", {})
    for k, v in meta.items():
        model.metadata_props.add(key=k, value=v)
    onnx.save(model, str(path))
    return path


def test_model_graphs_are_checked_against_their_metadata(tmp_path):
    from onnx import TensorProto
    from signlane.onnx_model import ModelError
    from signlane.signs.classifier import SignClassifier
    good = SignClassifier(sign_model(tmp_path / "good.onnx"))
    assert good.probabilities([np.zeros((40, 40, 3), np.uint8)]).shape == (1, 7)
    cases = {
        "three.onnx": (dict(n_out=3), r"graph output is \(2, 3\) for a batch of 2; the contract is \(batch, classes\) "
                                      r"with the 7 classes the metadata lists"),
        "identity.onnx": (dict(identity=True), r"graph output is \(2, 3, 32, 32\)"),
        "double.onnx": (dict(dtype=TensorProto.DOUBLE), r"graph input 'input' is tensor\(double\), the contract is "
                                                         r"tensor\(float\)"),
        "size.onnx": (dict(size=48), r"graph input 'input' is \(batch, 3, 48, 48\); the metadata says "
                                      r"\(batch, 3, 32, 32\)"),
    }
    for name, (kw, match) in cases.items():
        with pytest.raises(ModelError, match=match) as e:
            SignClassifier(sign_model(tmp_path / name, **kw))
        assert str(e.value).startswith(str(tmp_path / name)) and "\n" not in str(e.value)


def test_a_lane_model_with_the_wrong_output_is_refused(tmp_path):
    from signlane.lanes.seg_model import TASK, LaneSegModel
    from signlane.onnx_model import ModelError
    path = sign_model(tmp_path / "lanes.onnx", identity=True, classes=["background", "lane_marking"], task=TASK,
                      size=32)
    with pytest.raises(ModelError, match=r"graph output is \(2, 3, 32, 32\) .* the contract is "
                                         r"\(batch, classes, h, w\) with the 2 classes"):
        LaneSegModel(path)


# ---------------------------------------------------------------------- 2. no bound on pixels
def jpeg_claiming(image, width: int, height: int) -> bytes:
    """A real JPEG whose frame header (SOF0) claims another size."""
    d = bytearray(encode_jpeg(image))
    i = d.index(b"\xff\xc0")
    d[i + 5:i + 9] = struct.pack(">HH", height, width)
    return bytes(d)


def png_claiming(image, width: int, height: int) -> bytes:
    d = bytearray(cv2.imencode(".png", image)[1].tobytes())
    d[16:24] = struct.pack(">II", width, height)
    d[29:33] = struct.pack(">I", zlib.crc32(bytes(d[12:29])))
    return bytes(d)


def test_the_server_refuses_images_over_the_pixel_limit_from_their_header(road, caplog):
    caplog.set_level(logging.INFO, logger="signlane.drive")
    with DriveServer(options=ServerOptions(port=0, max_pixels=100 * 100)) as srv:
        with connect(srv.url) as ws:
            assert ask(ws, tel(road[0])) == SAFE
            ask(ws, tel(cv2.resize(road[0], (80, 60))))  # under the limit: decoded and driven
    line, = warnings_of(caplog, "client 1")
    assert line == ("client 1: telemetry 'image': image is 320x240 px, over the limit of 10000 pixels (100x100); "
                    "answered with the safe command")
    with DriveServer(options=ServerOptions(port=0)) as srv:  # the default limit, 4096x4096
        with connect(srv.url) as ws:
            assert ask(ws, tel(jpeg_claiming(road[0], 12000, 12000))) == SAFE
            assert ask(ws, tel(road[0])) != SAFE


def test_infer_refuses_a_huge_png_in_one_line_and_goes_on(tmp_path, road, capsys):
    (tmp_path / "huge.png").write_bytes(png_claiming(road[0], 20000, 20000))
    cv2.imwrite(str(tmp_path / "ok.png"), road[0])
    code = main(["infer", "--no-progress", str(tmp_path / "huge.png"), str(tmp_path / "ok.png"), "--json", "-"])
    out, err = capsys.readouterr()
    assert code == 1
    lines = [line for line in err.splitlines() if line.startswith("signlane infer:")]
    assert lines == [f"signlane infer: {tmp_path / 'huge.png'}: image is 20000x20000 px, over the limit of "
                     "16777216 pixels (4096x4096)"]
    assert [json.loads(line)["source"] for line in out.splitlines()] == [str(tmp_path / "ok.png")]
    code = main(["infer", "--no-progress", str(tmp_path / "ok.png"), "--max-pixels", "100x100"])
    assert code == 1 and "over the limit of 10000 pixels (100x100)" in capsys.readouterr().err


def test_video_frames_over_the_limit_are_refused(tmp_path, road):
    from signlane.media import MediaError, iter_video
    path = write_video(tmp_path / "v.avi", road * 2)
    with pytest.raises(MediaError, match="v.avi: video frame: image is 320x240 px, over the limit of 10000 pixels"):
        next(iter_video(path, max_pixels=100 * 100))


class CountingDriver:
    def __init__(self):
        self.steps = 0

    def step(self, t):
        self.steps += 1
        return Perception(None, LaneEstimate("fake", True)), Command(0.1, 0.5, "cruise")

    def close(self):
        pass


def test_a_frame_of_a_closed_connection_is_not_driven(road, monkeypatch):
    """The client sends a frame and leaves while it is being decoded: the step is skipped (with
    a huge frame it would have kept the CPU busy for nobody)."""
    import signlane.sim.server as server_mod
    real = server_mod.decode_telemetry
    decoding = threading.Event()

    def slow_decode(*args):
        decoding.set()
        time.sleep(0.5)
        return real(*args)
    drivers = []

    def factory():
        drivers.append(CountingDriver())
        return drivers[-1]
    with DriveServer(options=ServerOptions(port=0), driver_factory=factory) as srv:
        with connect(srv.url) as ws:
            assert ask(ws, tel(road[0])) == {"throttle": 0.5, "steering": 0.1}
            monkeypatch.setattr(server_mod, "decode_telemetry", slow_decode)
            ws.send(tel(road[0], 1))
            assert decoding.wait(10)
        # the client has left; the server finishes that decode before it stops
    assert drivers[-1].steps == 1


# ---------------------------------------------------------------------- 3. corrupt JPEG data
def corrupt_jpeg(image, seed: int = 4) -> bytes:
    d = bytearray(encode_jpeg(image))
    mid = len(d) // 2
    d[mid:mid + 40] = np.random.default_rng(seed).integers(0, 256, 40, dtype=np.uint8).tobytes()
    return bytes(d)


def jpeg_fault(data: bytes) -> str:
    """What the image check finds wrong with a JPEG (it must find something)."""
    from signlane import imagecheck
    with pytest.raises(imagecheck.ImageCheckError) as e:
        imagecheck.check_jpeg(data)
    reason = str(e.value)
    assert reason.startswith("corrupt JPEG data (") and " in the scan at byte " in reason and "\n" not in reason
    return reason


def test_a_corrupt_jpeg_gets_the_safe_answer_one_line_and_no_libjpeg_text(road, caplog, capfd):
    caplog.set_level(logging.INFO, logger="signlane.drive")
    bad = corrupt_jpeg(road[0])
    with DriveServer(options=ServerOptions(port=0)) as srv:
        with connect(srv.url) as ws:
            assert ask(ws, tel(road[0], 0)) != SAFE
            assert ask(ws, tel(bad, 1)) == SAFE
            assert ask(ws, tel(road[0], 2)) != SAFE
    assert srv.totals["bad"] == 1
    line, = warnings_of(caplog, "corrupt")
    assert line == f"client 1: telemetry 'image': {jpeg_fault(bad)}; answered with the safe command"
    assert "Corrupt JPEG data" not in capfd.readouterr().err  # libjpeg never saw it


def test_infer_refuses_a_corrupt_jpeg(tmp_path, road, capsys):
    (tmp_path / "bad.jpg").write_bytes(corrupt_jpeg(road[0]))
    assert main(["infer", "--no-progress", str(tmp_path / "bad.jpg")]) == 1
    err = capsys.readouterr().err
    assert f"signlane infer: {tmp_path / 'bad.jpg'}: {jpeg_fault(corrupt_jpeg(road[0]))}\n" in err


# ---------------------------------------------------------------------- 5. one line, not a traceback
def test_an_unreadable_folder_fails_alone(tmp_path, road, capsys, monkeypatch):
    locked = tmp_path / "locked"
    locked.mkdir()
    cv2.imwrite(str(locked / "a.png"), road[0])
    cv2.imwrite(str(tmp_path / "ok.png"), road[0])
    real = Path.iterdir

    def iterdir(self):
        if self == locked:
            raise PermissionError(13, "Permission denied", str(self))
        return real(self)
    monkeypatch.setattr(Path, "iterdir", iterdir)  # chmod 000 does not stop root
    code = main(["infer", "--no-progress", str(locked), str(tmp_path / "ok.png"), "--json", "-"])
    out, err = capsys.readouterr()
    assert code == 1
    assert [line for line in err.splitlines() if line.startswith("signlane infer:")] == [
        f"signlane infer: {locked}: cannot list the folder (Permission denied)"]
    assert len(out.splitlines()) == 1


def test_unwritable_outputs_are_one_line(tmp_path, road, capsys):
    cv2.imwrite(str(tmp_path / "ok.png"), road[0])
    blocker = tmp_path / "file.txt"
    blocker.write_text("a file, not a folder")
    assert main(["infer", "--no-progress", str(tmp_path / "ok.png"), "--out", str(blocker / "out")]) == 2
    assert "--out" in one_error_line(capsys.readouterr().err, "infer")
    assert main(["infer", "--no-progress", str(tmp_path / "ok.png"), "--json", str(blocker / "x.jsonl")]) == 2
    assert "--json" in one_error_line(capsys.readouterr().err, "infer")


def test_the_json_file_is_never_half_written(tmp_path, road, capsys, monkeypatch):
    from signlane.pipeline import Pipeline
    for i in range(3):
        cv2.imwrite(str(tmp_path / f"f{i}.png"), road[i])
    js = tmp_path / "out.jsonl"
    real = Pipeline.step
    calls = []

    def step(self, frame, speed=0.0):
        calls.append(1)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return real(self, frame, speed)
    monkeypatch.setattr(Pipeline, "step", step)
    args = ["infer", "--no-progress", *(str(tmp_path / f"f{i}.png") for i in range(3)), "--json", str(js)]
    assert main(args) == 130
    assert not js.exists() and not list(tmp_path.glob(".*tmp*"))
    monkeypatch.setattr(Pipeline, "step", real)
    assert main(args) == 0
    assert len(js.read_text().splitlines()) == 3


def test_sim_with_driver_and_a_bad_model_is_one_line(capsys):
    code = main(["sim", "--with-driver", "--lockstep", "--max-seconds", "2", "--set", "signs.model=/nonexistent.onnx"])
    assert code == 2
    assert one_error_line(capsys.readouterr().err, "sim").endswith("/nonexistent.onnx: model file not found")


def test_gen_lanes_with_a_junction_share_over_one_is_one_line(tmp_path, capsys):
    code = main(["gen", "lanes", "--n", "4", "--out", str(tmp_path / "set"), "--junctions", "2"])
    assert code == 2
    assert one_error_line(capsys.readouterr().err, "gen").endswith("junctions is a share of the frames, 0..1, not 2.0")
    assert not (tmp_path / "set").exists()


@pytest.fixture(scope="module")
def crops(tmp_path_factory):
    from signlane_data.signs import generate_signs
    # Lightning's loggers keep the sys.stderr of their first import: not a test's capsys stream
    import signlane_train.signs  # noqa: F401
    root = tmp_path_factory.mktemp("crops")
    generate_signs(root, 140, seed=5, crop=32)
    return root


def _train(crops, out, *extra) -> int:
    return main(["train", "signs", str(crops), "--out", str(out), "--batch-size", "32", "--workers", "0",
                 "--threads", "1", *extra])


def test_resume_from_a_truncated_checkpoint_is_one_line(crops, tmp_path, capsys):
    assert _train(crops, tmp_path / "run", "--epochs", "1") == 0
    last = tmp_path / "run" / "checkpoints" / "last.ckpt"
    last.write_bytes(last.read_bytes()[: last.stat().st_size // 2])  # killed while saving
    capsys.readouterr()
    assert _train(crops, tmp_path / "run", "--epochs", "2", "--resume") == 2
    line = one_error_line(capsys.readouterr().err, "train")
    assert f"--resume: {last} is damaged" in line and "best.ckpt" in line


# ---------------------------------------------------------------------- 9. resume and repeat training
def test_last_checkpoint_is_every_epoch_and_resume_continues_from_it(crops, tmp_path, monkeypatch):
    import torch
    from signlane_train.sign_task import SignTask
    from signlane_train.signs import train_signs
    out = tmp_path / "run"

    def worse_every_epoch(self):  # the monitored metric never improves after the first epoch
        self.log("val/acc", torch.tensor(0.9 - 0.1 * self.current_epoch))
        for m in (self.val_acc, self.val_f1, self.val_recall, self.val_confusion):
            m.reset()

    def killed_in_epoch_2(self):
        if self.current_epoch == 2:
            raise RuntimeError("killed")
    monkeypatch.setattr(SignTask, "on_validation_epoch_end", worse_every_epoch)
    monkeypatch.setattr(SignTask, "on_train_epoch_start", killed_in_epoch_2, raising=False)
    with pytest.raises(RuntimeError, match="killed"):
        train_signs([crops], out, epochs=3, batch_size=32, quiet=True, threads=1)
    load = lambda name: torch.load(out / "checkpoints" / name, map_location="cpu", weights_only=False)  # noqa: E731
    assert load("best.ckpt")["epoch"] == 0
    last = load("last.ckpt")
    assert last["epoch"] == 1  # the last finished epoch, not the last improvement
    per_epoch = last["global_step"] // 2
    assert per_epoch > 0 and last["global_step"] == 2 * per_epoch
    monkeypatch.undo()
    monkeypatch.setattr(SignTask, "on_validation_epoch_end", worse_every_epoch)
    train_signs([crops], out, epochs=3, batch_size=32, quiet=True, threads=1, resume=True)
    last = load("last.ckpt")
    assert last["epoch"] == 2 and last["global_step"] == 3 * per_epoch  # one more epoch, none again


def test_deterministic_training_repeats_exactly(crops, tmp_path, capsys):
    """Deterministic is the default: the same seed, with a worker process augmenting, gives the
    same weights and the same ONNX outputs on a fixed batch; another seed does not."""
    import torch
    from signlane.signs.classifier import SignClassifier
    from signlane_export.signs import export_signs
    fixed = [cv2.imread(str(p)) for p in sorted(crops.rglob("*.png"))[:48]]
    states, outputs = [], []
    for k, seed in enumerate(("3", "3", "4")):
        assert _train(crops, tmp_path / f"r{k}", "--epochs", "1", "--seed", seed, "--workers", "1") == 0
        ckpt = tmp_path / f"r{k}" / "checkpoints" / "last.ckpt"
        states.append(torch.load(ckpt, map_location="cpu", weights_only=False)["state_dict"])
        export_signs(ckpt, tmp_path / f"r{k}.onnx")
        outputs.append(SignClassifier(tmp_path / f"r{k}.onnx").probabilities(fixed))
    assert states[0].keys() == states[1].keys()
    assert max(float((states[0][k].float() - states[1][k].float()).abs().max()) for k in states[0]) == 0.0
    assert np.array_equal(outputs[0], outputs[1]) and not np.allclose(outputs[0], outputs[2], atol=1e-4)
    config = json.loads((tmp_path / "r0" / "config.json").read_text())
    assert config["deterministic"] is True and config["workers"] == 1


def test_each_data_loader_worker_draws_its_own_augmentations(crops):
    """albumentations keeps its own generator: without a per-worker seed, two workers would start
    from one copy of it and augment the same crop identically."""
    import lightning as L
    import torch
    from signlane_train.sign_data import SignDataModule
    dm = SignDataModule([crops], batch_size=4, workers=2, seed=0)
    dm.setup()
    dm.train_items = [dm.train_items[0]] * 8  # one crop, so only the augmentations can differ
    L.seed_everything(0)
    batches = [b[0] for b in dm.train_dataloader()]  # workers take turns: batch 0 from one, 1 from the other
    assert len(batches) == 2 and not torch.equal(batches[0], batches[1])


# ---------------------------------------------------------------------- 6. config ranges
@pytest.mark.parametrize("override, message", [
    ("camera.hfov_deg=0", "camera.hfov_deg = 0.0 is outside 1..179 degrees"),
    ("camera.height_m=0", "camera.height_m = 0.0 is outside 0.05..50 m"),
    ("camera.pitch_deg=nan", "camera.pitch_deg = nan is not a finite number"),
    ("camera.roll_deg=inf", "camera.roll_deg = inf is not a finite number"),
    ("control.cruise=5", "control.cruise = 5.0 is outside 0..1 (throttle)"),
    ("signs.variant=bogus", "signs.variant = 'bogus' is not one of robust, published"),
    ("lanes.variant=fast", "lanes.variant = 'fast' is not one of robust, published"),
    ("signs.confirm_n=2.7", "--set signs.confirm_n=2.7: confirm_n = 2.7 is not a whole number"),
    ("signs.confirm_n=9", "signs.confirm_n = 9 is more than signs.confirm_m = 5"),
    ("signs.min_score=1.5", "signs.min_score = 1.5 is outside 0..1"),
    ("drive.max_speed=0", "drive.max_speed = 0.0 is outside 0.1..100 m/s"),
    ("drive.cruise_speed=-1", "drive.cruise_speed = -1.0 is outside 0..100 m/s"),
    ("drive.wheelbase_m=0", "drive.wheelbase_m = 0.0 is outside 0.05..20 m"),
    ("drive.lanes_width=8", "drive.lanes_width = 8 is outside 32..8192 px (or 0: off)"),
])
def test_config_values_are_range_checked(override, message):
    with pytest.raises(ValueError) as e:
        Config.load(None, [override])
    assert message in str(e.value) and "\n" not in str(e.value)


def test_generous_physical_values_are_accepted():
    cfg = Config.load(None, ["camera.hfov_deg=75.2", "camera.height_m=2.9", "camera.pitch_deg=11.8",
                             "drive.max_speed=13.41", "drive.wheelbase_m=1.957", "drive.lanes_width=0",
                             "signs.confirm_n=6", "signs.confirm_m=8", "signs.confirm_n=2.0", "camera.pitch_deg=-20"])
    assert (cfg.signs.confirm_n, cfg.signs.confirm_m, cfg.camera.pitch_deg) == (2, 8, -20.0)


def test_a_bad_config_value_stops_infer_and_drive_in_one_line(tmp_path, road, capsys):
    cv2.imwrite(str(tmp_path / "ok.png"), road[0])
    assert main(["infer", "--no-progress", str(tmp_path / "ok.png"), "--set", "camera.hfov_deg=0"]) == 2
    assert "camera.hfov_deg = 0.0 is outside 1..179" in one_error_line(capsys.readouterr().err, "infer")
    assert main(["drive", "--port", "0", "--set", "camera.height_m=0"]) == 2
    assert "camera.height_m = 0.0 is outside" in one_error_line(capsys.readouterr().err, "drive")


# ---------------------------------------------------------------------- 7. videos that break part-way
def write_video(path: Path, frames, fourcc: str = "MJPG") -> Path:
    w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*fourcc), 10, frames[0].shape[1::-1])
    for f in frames:
        w.write(f)
    w.release()
    return path


def test_a_truncated_video_says_how_many_frames_it_gave(tmp_path, road, capsys):
    full = write_video(tmp_path / "full.avi", [road[i % 3] for i in range(30)])
    data = full.read_bytes()
    (tmp_path / "cut.avi").write_bytes(data[: len(data) // 2])
    js = tmp_path / "out.jsonl"
    code = main(["infer", "--no-progress", str(tmp_path / "cut.avi"), str(full), "--json", str(js)])
    err = capsys.readouterr().err
    assert code == 1
    lines = [line for line in err.splitlines() if line.startswith("signlane infer:")]
    assert len(lines) == 1 and lines[0].startswith(f"signlane infer: {tmp_path / 'cut.avi'}: video ended after ")
    assert lines[0].endswith(" of the 30 frames its container lists (truncated or corrupt)")
    n = int(lines[0].split("ended after ")[1].split()[0])
    recs = [json.loads(line) for line in js.read_text().splitlines()]
    assert 0 < n < 30 and sum(r["source"].endswith("cut.avi") for r in recs) == n
    assert sum(r["source"].endswith("full.avi") for r in recs) == 30


# ---------------------------------------------------------------------- 8. the server's error log
def test_each_client_gets_its_own_error_line(road, caplog):
    caplog.set_level(logging.INFO, logger="signlane.drive")
    with DriveServer(options=ServerOptions(port=0)) as srv:
        with connect(srv.url) as a, connect(srv.url) as b:
            assert ask(a, "not json") == SAFE
            assert ask(b, "not json") == SAFE
    lines = warnings_of(caplog, "not JSON")
    assert [line.split(":")[0] for line in lines] == ["client 1", "client 2"]


def test_repeats_on_one_connection_are_summed_up_when_it_ends(road, caplog):
    caplog.set_level(logging.INFO, logger="signlane.drive")
    with DriveServer(options=ServerOptions(port=0)) as srv:
        with connect(srv.url) as ws:
            for _ in range(40):
                assert ask(ws, "[1, 2") == SAFE
            assert ask(ws, tel(road[0])) != SAFE
    lines = warnings_of(caplog, "not JSON")
    assert len(lines) == 2 and "(repeated 39 times in the last" in lines[1]
    assert srv.totals["bad"] == 40


def test_error_log_summarises_repeats_once_their_window_has_passed():
    from signlane.sim.drive_stats import ErrorLog
    lines = []
    errors = ErrorLog(window_s=10.0, logger=logging.getLogger("test.errorlog"))
    errors.logger.warning = lambda fmt, *a: lines.append(fmt % a)
    for t in range(5):
        errors.warning(f"frame {t} is bad", now=float(t), who="client 1")
    errors.warning("frame 9 is bad", now=1.0, who="client 2")
    assert errors.flush(now=5.0) == 0  # within the window: nothing yet
    assert errors.flush(now=10.5) == 1
    assert lines == ["client 1: frame 0 is bad", "client 2: frame 9 is bad",
                     "client 1: frame 4 is bad (repeated 4 times in the last 10 s)"]
    assert errors.flush(now=30.0) == 0 and errors.flush(who="client 1") == 0


def test_an_invalid_utf8_frame_is_logged_as_such(caplog):
    caplog.set_level(logging.INFO, logger="signlane.drive")
    with DriveServer(options=ServerOptions(port=0)) as srv:
        sock = socket.create_connection(("127.0.0.1", srv.port), timeout=10)
        sock.sendall(b"GET / HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                     b"Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n")
        reply = b""
        while b"\r\n\r\n" not in reply:
            reply += sock.recv(4096)
        payload = b"\xff\xfe not utf-8"
        sock.sendall(bytes([0x81, 0x80 | len(payload)]) + b"\0\0\0\0" + payload)  # masked text frame
        time.sleep(0.5)
        sock.close()
        time.sleep(0.3)
    dropped = [r.getMessage() for r in caplog.records if "dropped" in r.getMessage()]
    assert len(dropped) == 1 and "a text frame that is not valid UTF-8" in dropped[0], dropped
    assert "closed with 1007); no frames driven" in dropped[0]  # then the connection's latency split


# ---------------------------------------------------------------------- 10. gen --resume verifies
def _hashes(root: Path) -> dict[str, str]:
    import hashlib
    out = {}
    for p in sorted(root.rglob("*")):
        if p.is_file() and p.name != "manifest.json":
            out[str(p.relative_to(root))] = hashlib.sha1(p.read_bytes()).hexdigest()
    return out


def test_gen_resume_remakes_damaged_files(tmp_path, monkeypatch):
    from signlane_data import lanes as lanes_mod
    ref, out = tmp_path / "ref", tmp_path / "out"
    lanes_mod.generate_lanes(ref, 6, seed=3, width=160, height=120)
    generate_lanes_killed_at(out, 5, monkeypatch, 6, seed=3, width=160, height=120)
    # frames 0-4 were written; a crash before the disk flushed them leaves damaged files
    image = out / "images" / "000002.jpg"
    image.write_bytes(image.read_bytes()[:200])
    mask = out / "masks" / "000004.png"
    m = bytearray(mask.read_bytes())
    m[len(m) // 2] ^= 0xFF
    mask.write_bytes(bytes(m))
    (out / "images" / "000003.jpg").write_bytes(b"")
    lanes_mod.generate_lanes(out, 6, seed=3, width=160, height=120, resume=True)
    assert _hashes(out) == _hashes(ref)


def test_gen_signs_resume_remakes_damaged_crops(tmp_path):
    from signlane_data.signs import generate_signs
    ref, out = tmp_path / "ref", tmp_path / "out"
    generate_signs(ref, 60, seed=2, crop=32)
    generate_signs(out, 60, seed=2, crop=32)
    (out / "manifest.json").unlink()
    crops = sorted(out.rglob("*.png"))
    for p in crops[::7]:
        p.write_bytes(p.read_bytes()[:-30])
    generate_signs(out, 60, seed=2, crop=32, resume=True)
    assert _hashes(out) == _hashes(ref)
