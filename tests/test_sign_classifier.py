"""Sign classifier: smoke training -> ONNX export -> onnxruntime parity, and model-file errors."""
import json

import cv2
import numpy as np
import onnx
import pytest
import torch

from signlane.onnx_model import ModelError, make_metadata
from signlane.signs.classifier import DEFAULT_SPEC, TASK, SignClassifier, preprocess_crops
from signlane.signs.confirm import SignConfirmer
from signlane.types import SignDetection
from signlane.world.art import SIGN_CLASSES


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """A 1-epoch run on a tiny generated crop set, exported to ONNX (int8 too)."""
    from signlane_data.signs import generate_signs
    from signlane_export.signs import export_signs
    from signlane_train.signs import train_signs
    root = tmp_path_factory.mktemp("signs")
    generate_signs(root / "data", 140, seed=5, crop=32)
    report = train_signs([root / "data"], root / "run", epochs=1, batch_size=32, quiet=True)
    onnx_path = root / "signs.onnx"
    exported = export_signs(report["best_checkpoint"], onnx_path, int8=True)
    return root, report, onnx_path, exported


def test_smoke_training_writes_its_outputs(trained):
    root, report, _, _ = trained
    run = root / "run"
    for name in ("checkpoints/last.ckpt", "config.json", "confusion.png"):
        assert (run / name).exists(), name
    assert list((run / "logs").rglob("metrics.csv")) and list((run / "tensorboard").rglob("events.*"))
    assert 0.0 <= report["accuracy"] <= 1.0 and set(report["recall"]) == set(SIGN_CLASSES)


def test_train_command_runs_either_kind_and_reports_bad_data_in_one_line(trained, tmp_path, capsys):
    from signlane.cli import main
    root = trained[0]
    # a config file sets what the command line leaves alone; any Lightning Trainer argument is a flag
    (tmp_path / "train.toml").write_text("[train]\nepochs = 1\nbatch_size = 16\naugment = 0.25\n"
                                         "[trainer]\nlimit_train_batches = 3\n")
    code = main(["train", "signs", str(root / "data"), "--out", str(tmp_path / "run"), "--config",
                 str(tmp_path / "train.toml"), "--batch-size", "32", "--workers", "0", "--threads", "1",
                 "--augment", "0.5", "--trainer.gradient_clip_val", "0.5", "--trainer.limit_val_batches", "2"])
    out = capsys.readouterr().out
    assert "accuracy" in json.loads(out[out.index("{\n"):])
    assert code == 0 and (tmp_path / "run" / "checkpoints" / "last.ckpt").exists()
    config = json.loads((tmp_path / "run" / "config.json").read_text())
    assert config["threads"] == 1 and config["augment"] == 0.5 and config["batch_size"] == 32 and config["epochs"] == 1
    assert config["trainer"] == {"limit_train_batches": 3, "gradient_clip_val": 0.5, "limit_val_batches": 2}
    ckpt = torch.load(tmp_path / "run" / "checkpoints" / "last.ckpt", map_location="cpu", weights_only=False)
    assert ckpt["global_step"] == 3  # one epoch of 3 batches (limit_train_batches), not the whole set
    # the run's train.toml repeats it: the same options, resolved
    assert main(["train", "signs", "--config", str(tmp_path / "run" / "train.toml"), "--print-config"]) == 0
    again = capsys.readouterr().out
    assert again == (tmp_path / "run" / "train.toml").read_text() and "gradient_clip_val = 0.5" in again
    for kind in ("signs", "lanes"):
        assert main(["train", kind, str(tmp_path / "none"), "--out", str(tmp_path / kind)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and all("none" in line for line in err)
    # a Trainer argument Lightning refuses for this data: its reason, in one line
    assert main(["train", "signs", str(root / "data"), "--out", str(tmp_path / "bad"), "--epochs", "1",
                 "--workers", "0", "--trainer.limit_train_batches", "0.0001"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "limit_train_batches" in err[0], err


def test_export_matches_torch_and_carries_its_contract(trained):
    root, report, onnx_path, exported = trained
    assert exported["parity_max_abs"] <= 1e-4
    model = onnx.load(str(onnx_path))
    onnx.checker.check_model(model)
    meta = {p.key: p.value for p in model.metadata_props}
    assert meta["signlane.task"] == TASK and json.loads(meta["signlane.classes"]) == list(SIGN_CLASSES)
    # dynamic batch: the runtime classifies 1 and 37 crops in one go each
    clf = SignClassifier(onnx_path)
    crops = [cv2.imread(str(p)) for p in sorted((root / "data").rglob("*.png"))[:37]]
    assert clf.probabilities(crops[:1]).shape == (1, 7) and clf.probabilities(crops).shape == (37, 7)
    # the runtime's preprocessing fed to torch gives the ONNX answer (one preprocessing path)
    import torch
    from signlane_train.sign_task import SignTask
    task = SignTask.load_from_checkpoint(report["best_checkpoint"], map_location="cpu").eval()
    with torch.no_grad():
        ref = torch.softmax(task(torch.from_numpy(preprocess_crops(crops, DEFAULT_SPEC))), 1).numpy()
    assert np.max(np.abs(ref - clf.probabilities(crops))) < 1e-4
    assert "accuracy_drop" in exported["int8"] and (root / "signs_int8.onnx").exists()


def test_quantize_makes_an_int8_classifier_that_keeps_the_labels(trained, tmp_path, capsys):
    from signlane.cli import main
    from signlane.ship import MODELS_DIR
    root, _, onnx_path, _ = trained
    out = tmp_path / "q" / "signs.onnx"
    capsys.readouterr()
    assert main(["quantize", "signs", str(onnx_path), "--data", str(root / "data"), "--out", str(out)]) == 0
    report = json.loads(capsys.readouterr().out)
    graph = onnx.load(str(out))
    assert any(n.op_type == "QuantizeLinear" for n in graph.graph.node)  # int8 inside, the fp32 contract outside
    meta = {p.key: p.value for p in graph.metadata_props}
    assert meta["signlane.task"] == TASK and "int8" in meta["signlane.quantized"]
    assert report["int8"]["calibration_crops"] == report["val_crops"] > 0
    # the labels the fp32 file gives, on crops it was not calibrated with as on those it was
    crops = [cv2.imread(str(p)) for p in sorted((root / "data").rglob("*.png"))]
    fp32, int8 = SignClassifier(onnx_path).probabilities(crops), SignClassifier(out).probabilities(crops)
    assert (fp32.argmax(1) == int8.argmax(1)).mean() >= 0.95 and np.abs(fp32 - int8).max() < 0.2
    assert report["int8"]["agreement"] >= 0.95 and abs(report["int8"]["accuracy_drop"]) <= 0.05
    # an int8 file again, the shipped models' folder, a folder that holds no crop set: one line each
    for argv, words in ((["quantize", "signs", str(out), "--data", str(root / "data"), "--out", str(tmp_path / "qq.onnx")],
                         "already quantized"),
                        (["quantize", "signs", str(onnx_path), "--data", str(root / "data"), "--out",
                          str(MODELS_DIR / "signs.onnx")], "signlane ship"),
                        (["quantize", "signs", str(onnx_path), "--data", str(tmp_path / "none"), "--out",
                          str(tmp_path / "qq.onnx")], "none")):
        assert main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and words in err[0], err
    assert not (tmp_path / "qq.onnx").exists()


def test_missing_corrupt_and_foreign_models_give_clear_errors(tmp_path, trained):
    _, _, onnx_path, _ = trained
    with pytest.raises(ModelError, match="not found"):
        SignClassifier(tmp_path / "none.onnx")
    bad = tmp_path / "bad.onnx"
    bad.write_bytes(b"garbage" * 100)
    with pytest.raises(ModelError, match="not a loadable ONNX model"):
        SignClassifier(bad)
    model = onnx.load(str(onnx_path))
    for key, value, match in [("signlane.task", "lane-segmentation", "expected 'sign-classifier'"),
                              ("signlane.contract", "99", "contract '99' is not supported"),
                              ("signlane.classes", "not json", "'classes' is missing"),
                              ("signlane.input", '{"size": [32]}', "'input' is malformed")]:
        m = onnx.ModelProto()
        m.CopyFrom(model)
        for p in m.metadata_props:
            if p.key == key:
                p.value = value
        path = tmp_path / f"meta_{key.split('.')[-1]}.onnx"
        onnx.save(m, str(path))
        with pytest.raises(ModelError, match=match):
            SignClassifier(path)


def test_metadata_without_unknown_class_is_refused(tmp_path, trained):
    _, _, onnx_path, _ = trained
    m = onnx.load(str(onnx_path))
    meta = make_metadata(TASK, ["a", "b", "c", "d", "e", "f", "g"], DEFAULT_SPEC, "x", {})
    for p in m.metadata_props:
        if p.key in meta:
            p.value = meta[p.key]
    path = tmp_path / "nounknown.onnx"
    onnx.save(m, str(path))
    with pytest.raises(ModelError, match="lack 'unknown'"):
        SignClassifier(path)


def test_confirmation_needs_n_of_m_frames():
    c = SignConfirmer(3, 5)
    stop = SignDetection("stop", 0.9, (10, 10, 30, 30))
    seen = [c.step([stop] if k in (0, 2, 4) else []) for k in range(5)]
    assert [len(s) for s in seen] == [0, 0, 0, 0, 1]  # confirmed on its third sighting in five frames
    c.reset()
    assert all(not c.step([stop] if k % 3 == 0 else []) for k in range(9))  # one in three never confirms


def test_autolabel_files_proposals_by_the_classifier_and_draws_sheets(tmp_path, trained, capsys):
    from signlane.cli import main
    from signlane.world.sampling import FrameSampler, SamplerConfig
    _, _, onnx_path, _ = trained
    sampler = FrameSampler(5, SamplerConfig(width=640, height=480, focus="signs", effects="clean"))
    for i in range(4):
        cv2.imwrite(str(tmp_path / f"f{i}.png"), sampler.sample(i).image)
    (tmp_path / "broken.png").write_bytes(b"nope")
    out = tmp_path / "labelled"
    code = main(["autolabel", "signs", str(tmp_path), "--out", str(out), "--model", str(onnx_path)])
    report = json.loads(capsys.readouterr().out)
    assert code == 1  # the broken file is reported, the rest is filed
    total = sum(report["counts"].values())
    assert total > 0 and total == len(list(out.rglob("*_??.png")))
    for label, n in report["counts"].items():
        assert label in SIGN_CLASSES and (out / f"sheet_{label}.png").exists()


def test_shipped_model_meets_a_floor_on_a_fresh_seeded_set(tmp_path):
    """The shipped model (see signlane/models/signs.json) on crops it never saw."""
    from signlane_data.signs import generate_signs
    from signlane.evaluate import eval_signs
    from signlane.signs.classifier import DEFAULT_MODEL
    card = json.loads(DEFAULT_MODEL.with_suffix(".json").read_text())
    assert card["classes"] == list(SIGN_CLASSES) and card["task"] == TASK
    generate_signs(tmp_path / "test", 400, seed=77)
    scores = eval_signs(tmp_path / "test")
    # the shipped model scores 100 % here (507 crops); ~47 crops a sign class make one error 2 %,
    # so the floor leaves room for a retrained model of the same quality (a broken one falls far
    # below it; the card has the scores on 3942 crops)
    assert scores["accuracy"] >= 0.98 and scores["non_sign_accepted"] <= 0.015
    assert all(r >= 0.95 for label, r in scores["recall"].items() if label != "unknown")


def test_sign_report_traces_every_wrong_crop_to_its_file(tmp_path):
    from signlane.sign_report import write_sign_report
    files = []
    for k in range(12):
        f = tmp_path / "crops" / f"crop_{k:03d}.png"
        f.parent.mkdir(exist_ok=True)
        cv2.imwrite(str(f), np.full((40, 40, 3), 20 * k, np.uint8))
        files.append(f)
    stop, left = SIGN_CLASSES.index("stop"), SIGN_CLASSES.index("left")
    y = np.array([stop] * 6 + [left] * 6)
    pred = y.copy()
    pred[[1, 4]] = left  # two stop signs taken for 'left'
    score = np.linspace(0.5, 0.95, 12)
    out = tmp_path / "report"
    (out).mkdir()
    (out / "errors_left.png").write_bytes(b"stale")  # none wrong now: must not stay behind
    write_sign_report(out, files, y, pred, score, SIGN_CLASSES, "test")
    assert cv2.imread(str(out / "confusion.png")) is not None
    assert not (out / "errors_left.png").exists()
    rows = (out / "errors_stop.txt").read_text().splitlines()[1:]
    assert [r.split("\t")[1] for r in rows] == [str(files[1]), str(files[4])]
    assert [r.split("\t")[2] for r in rows] == ["left", "left"] and rows[1].endswith(f"{score[4]:.4f}")
    sheet = cv2.imread(str(out / "errors_stop.png"))  # two 112 px tiles side by side, captions on a band below
    assert sheet.shape[1] == 2 * (112 + 2) + 2 and sheet.shape[0] > 112 + 2 * 14


def _frame_with_stop(size: int) -> tuple[np.ndarray, tuple[int, int, int, int]]:
    """A grey 160x120 frame with a stop sign of `size` px at (60, 40), and the sign's box."""
    from signlane.world.art import draw_sign
    frame = np.full((120, 160, 3), 90, np.uint8)
    sprite = draw_sign("stop", size)
    alpha = sprite[:, :, 3:] / 255.0
    patch = frame[40:40 + size, 60:60 + size]
    frame[40:40 + size, 60:60 + size] = (sprite[:, :, :3] * alpha + patch * (1 - alpha)).astype(np.uint8)
    return frame, (60, 40, size, size)


def test_washed_out_signs_are_not_examples_of_their_class():
    """A sign glare or exposure has turned into a flat patch (plus sensor noise) is left out of
    the crop set instead of teaching the classifier that blank patches are signs."""
    from signlane_data.sign_crops import MIN_FACE_CONTRAST, face_contrast
    rng = np.random.default_rng(0)
    frame, box = _frame_with_stop(40)
    assert face_contrast(frame, box) >= MIN_FACE_CONTRAST
    washed = np.clip(frame.astype(np.float32) * 10.0 + rng.normal(0, 8, frame.shape), 0, 255).astype(np.uint8)
    assert face_contrast(washed, box) < MIN_FACE_CONTRAST
    assert face_contrast(frame, (200, 200, 20, 20)) == 0.0  # a box off the image


def test_augmentation_dose_zero_leaves_crops_alone_and_full_dose_changes_them(tmp_path):
    from signlane_train.sign_data import CropDataset, train_augment
    crop = cv2.resize(np.dstack([np.arange(32 * 32, dtype=np.uint8).reshape(32, 32)] * 3), (48, 48))
    path = tmp_path / "stop.png"
    cv2.imwrite(str(path), crop)
    items = [(path, SIGN_CLASSES.index("stop"))]
    plain = CropDataset(items, DEFAULT_SPEC)[0][0]
    assert np.array_equal(CropDataset(items, DEFAULT_SPEC, train_augment(0.0))[0][0], plain)
    full = CropDataset(items, DEFAULT_SPEC, train_augment(1.0))
    assert sum(not np.array_equal(full[0][0], plain) for _ in range(10)) >= 8


def test_signs_the_camera_smeared_are_not_examples_but_noisy_ones_are():
    """The symbol-survival rule: a sign motion-blurred diagonally over 13 of its 32 px is left out
    of the crop set, one under ordinary sensor noise and a darker exposure is kept."""
    from types import SimpleNamespace
    from signlane_data.sign_crops import MIN_SYMBOL_SURVIVAL, symbol_survival, usable_sign
    from signlane.world.render import Sample
    rng = np.random.default_rng(0)
    clean, box = _frame_with_stop(32)
    sign = SimpleNamespace(box=box, occluded=0.0, truncated=0.0)
    noisy = np.clip(clean * 0.7 + rng.normal(0, 6, clean.shape), 0, 255).astype(np.uint8)
    smeared = cv2.filter2D(clean, -1, np.eye(13, dtype=np.float32) / 13)
    assert symbol_survival(Sample(noisy, None, clean), box) > 0.95 and usable_sign(sign, Sample(noisy, None, clean))
    assert symbol_survival(Sample(smeared, None, clean), box) < MIN_SYMBOL_SURVIVAL
    assert not usable_sign(sign, Sample(smeared, None, clean))
    assert symbol_survival(Sample(noisy, None, None), box) == 1.0  # no clean frame: nothing to compare
