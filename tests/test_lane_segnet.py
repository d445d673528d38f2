"""Learned lane segmentation: heavy data, autolabel, smoke training on mixed sets -> export ->
parity, the segnet method, model-file errors, and the shipped model's floor."""
import json

import cv2
import numpy as np
import onnx
import pytest

from signlane import lanes
from signlane.cli import main
from signlane.config import CameraConfig
from signlane.eval_masks import MaskCounts
from signlane.lanes import seg_model
from signlane.onnx_model import ModelError
from signlane.world.sampling import HEAVY, FrameSampler, SamplerConfig


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """Heavy synthetic frames + an autolabelled folder, 1 epoch on both, exported to ONNX."""
    from signlane_data.autolabel_lanes import autolabel_lanes
    from signlane_data.lanes import generate_lanes
    from signlane_export.lanes import export_lanes
    from signlane_train.lanes import train_lanes
    root = tmp_path_factory.mktemp("lanes")
    generate_lanes(root / "synthetic", 24, seed=5, preset="heavy")
    photos = root / "photos"
    photos.mkdir()
    smp = FrameSampler(3, SamplerConfig(effects="clean", randomise=False))
    for i in range(6):
        cv2.imwrite(str(photos / f"p{i}.png"), smp.sample(i).image)
    # painted-lane photos from their own camera, not VIA's (the default)
    cam = smp.sample(0).truth.camera
    # a dashed centre line beside a solid edge line: the default min_confidence keeps them
    auto = autolabel_lanes([str(photos)], root / "auto", camera=CameraConfig(cam.hfov_deg, cam.height_m, cam.pitch_deg),
                           progress=False)
    report = train_lanes([root / "synthetic", root / "auto"], root / "run", epochs=1, batch_size=8, workers=0,
                         quiet=True, eval_frames=8, threads=1)
    onnx_path = root / "lanes.onnx"
    exported = export_lanes(report["best_checkpoint"], onnx_path)
    return root, auto, report, onnx_path, exported


def test_heavy_preset_is_seeded_and_mixes_wide_frames():
    cfg = SamplerConfig(**HEAVY)
    a, b = FrameSampler(9, cfg), FrameSampler(9, cfg)
    shapes = set()
    for i in range(12):
        sa, sb = a.sample(i), b.sample(i)
        assert np.array_equal(sa.image, sb.image) and sa.image.shape[:2] == sa.truth.marking_mask.shape
        shapes.add(sa.image.shape[:2])
    assert shapes == {(240, 320), (180, 320)}


def test_world_preset_draws_any_cars_camera():
    from signlane.world.sampling import WORLD, WORLD_HEIGHT_M, WORLD_HFOV_DEG, WORLD_PITCH_DEG, world_camera
    rng = np.random.default_rng(0)
    h, p, f = np.array([(c.height_m, c.pitch_deg, c.hfov_deg) for c in
                        (world_camera(rng, 320, 240) for _ in range(400))]).T
    for v, (lo, hi) in ((h, WORLD_HEIGHT_M), (p, WORLD_PITCH_DEG), (f, WORLD_HFOV_DEG)):
        assert lo <= v.min() and v.max() <= hi and v.min() < lo + 0.1 * (hi - lo) and v.max() > hi - 0.1 * (hi - lo)
    assert np.median(h) < 1.0  # log-uniform: as many toy cars as dashcams
    # in the sampler (the rendered camera, with the effects' small jitter): far outside the heavy
    # preset's cameras (1-3.5 m high, pitched 3-22 degrees)
    world = FrameSampler(9, SamplerConfig(**WORLD))
    cams = np.array([(c.height_m, c.pitch_deg, c.hfov_deg) for c in (world.sample(i).truth.camera for i in range(40))])
    assert cams[:, 0].min() < 0.5 and cams[:, 1].min() < 2.0 and cams[:, 2].max() > 110


def test_autolabel_keeps_confident_frames_in_the_lane_layout(trained):
    root, auto, *_ = trained
    out = root / "auto"
    recs = [json.loads(line) for line in (out / "labels.jsonl").read_text().splitlines()]
    assert auto["counts"]["seen"] == 6 and len(recs) == auto["counts"]["kept"] == 6
    for r in recs:
        mask = cv2.imread(str(out / r["mask"]), cv2.IMREAD_UNCHANGED)
        assert mask.shape == (240, 320) and set(np.unique(mask)) == {0, 1, 255}
        # class ids: paint 1; the rows beyond the farthest paint the method labelled are 255 (unknown)
        top = np.flatnonzero((mask == 1).any(axis=1))[0]
        assert (mask[:top] == 255).all() and not (mask[top:] == 255).any()
        assert r["pseudo"]["confidence"] >= 0.7 and len(r["lane"]["left"]) > 1
    assert (out / "sheet.png").exists()
    assert json.loads((out / "manifest.json").read_text())["mask_encoding"] == "ids-0-1-255ignore"


def test_an_autolabel_run_that_keeps_nothing_says_so_and_training_refuses_it(trained, tmp_path, capsys):
    root = trained[0]
    blank = tmp_path / "blank"
    blank.mkdir()
    for i in range(3):  # no road to find
        cv2.imwrite(str(blank / f"b{i}.png"), np.full((240, 320, 3), 90, np.uint8))
    capsys.readouterr()
    assert main(["autolabel", "lanes", str(blank), "--out", str(tmp_path / "none")]) == 1
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip() and "%|" not in line]
    assert len(err) == 1 and "kept none of the 3 frames" in err[0] and "rejected.png" in err[0]
    code = main(["train", "lanes", str(root / "synthetic"), str(tmp_path / "none"), "--out", str(tmp_path / "run"),
                 "--epochs", "1", "--workers", "0"])
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip() and "%|" not in line]
    assert code == 2 and len(err) == 1
    assert f"{tmp_path / 'none'}: an empty training set" in err[0] and not (tmp_path / "run" / "checkpoints").exists()


def test_smoke_training_on_mixed_sets_writes_its_outputs(trained):
    root, _, report, _, _ = trained
    run = root / "run"
    for name in ("checkpoints/last.ckpt", "config.json", "samples/epoch_000.png"):
        assert (run / name).exists(), name
    assert list((run / "logs").rglob("metrics.csv")) and list((run / "tensorboard").rglob("events.*"))
    # both sets were trained on: every frame the stable split puts on the train side, from each
    from signlane.splits import split_of
    from signlane_train.lane_data import list_frames
    train = [it for it in list_frames([root / "synthetic", root / "auto"]) if split_of(it.key, 0.1) == "train"]
    assert {it.key.split("/")[0] for it in train} == {"synthetic", "auto"}
    assert json.loads((run / "config.json").read_text())["train_frames"] == len(train)
    assert 0.0 <= report["val_f1_at_2px"] <= 1.0 and report["parameters"] <= 500_000


def test_lane_training_repeats_exactly_by_default(trained, tmp_path):
    """The same seed, a worker process augmenting: the same ONNX outputs on a fixed batch."""
    from signlane_export.lanes import export_lanes
    from signlane_train.lanes import train_lanes
    root = trained[0]
    frames = [cv2.imread(str(p)) for p in sorted((root / "synthetic" / "images").glob("*.jpg"))[:6]]
    outputs = []
    for k in range(2):
        report = train_lanes([root / "synthetic"], tmp_path / f"r{k}", epochs=1, batch_size=8, workers=1,
                             quiet=True, eval_frames=4, threads=1, seed=7)
        export_lanes(report["best_checkpoint"], tmp_path / f"r{k}.onnx")
        outputs.append(seg_model.LaneSegModel(tmp_path / f"r{k}.onnx").probabilities(frames))
    assert np.array_equal(outputs[0], outputs[1])
    assert json.loads((tmp_path / "r0" / "config.json").read_text())["deterministic"] is True


def test_export_matches_torch_through_the_runtime_preprocessing(trained):
    import torch
    from signlane_train.lane_task import LaneTask
    root, _, report, onnx_path, exported = trained
    assert exported["parity_max_abs"] <= 1e-4
    meta = {p.key: p.value for p in onnx.load(str(onnx_path)).metadata_props}
    # autolabel wrote road masks beside the paint (road-edges was confident): a road model
    roads = (root / "auto" / "drivable").is_dir()
    want = seg_model.ROAD_CLASSES if roads else seg_model.CLASSES
    assert meta["signlane.task"] == seg_model.TASK and json.loads(meta["signlane.classes"]) == list(want)
    model = seg_model.LaneSegModel(onnx_path)
    frames = [cv2.imread(str(p)) for p in sorted((root / "synthetic" / "images").glob("*.jpg"))[:3]]
    got = model.probabilities(frames)
    task = LaneTask.load_from_checkpoint(report["best_checkpoint"], map_location="cpu").eval()
    with torch.no_grad():
        ref = seg_model.marking_probability(task(torch.from_numpy(seg_model.preprocess_frames(frames))).numpy())
    assert got.shape == (3, 120, 160) and np.max(np.abs(ref - got)) < 1e-4


def test_segnet_method_returns_a_lane_estimate_with_its_mask(trained):
    _, _, _, onnx_path, _ = trained
    image = FrameSampler(3, SamplerConfig(effects="clean", randomise=False)).sample(0).image
    for img in (image, cv2.cvtColor(image, cv2.COLOR_BGR2GRAY), image[:10, :10]):
        est = lanes.get("segnet", model=str(onnx_path))(img)
        assert est.method == "segnet" and est.with_masks().debug_mask.shape == img.shape[:2]


def test_segnet_puts_its_frame_sized_masks_off_until_asked(trained):
    """The car never waits for the network's masks at the frame's size: the estimate carries
    none, and `with_masks` makes exactly the masks the maps give at the frame's size."""
    from signlane.lanes.seg_model import LaneSegModel, to_frame_mask
    _, _, _, onnx_path, _ = trained
    image = cv2.resize(FrameSampler(3, SamplerConfig(effects="clean", randomise=False)).sample(0).image, (640, 480))
    est = lanes.get("segnet", model=str(onnx_path))(image)
    assert est.debug_mask is None and est.drivable_mask is None and est.masks_later is not None
    shown = est.with_masks()
    want = to_frame_mask(LaneSegModel(onnx_path).probabilities([image])[0], 640, 480)
    assert shown.masks_later is None and np.array_equal(shown.debug_mask, want) and want.any()
    assert shown.with_masks() is shown and shown.offset == est.offset and shown.found == est.found
    assert est.masks_later()[0] is est.masks_later()[0]  # made once, however many viewers ask


def test_missing_corrupt_and_foreign_models_give_clear_errors(tmp_path, capsys):
    bad = tmp_path / "bad.onnx"
    bad.write_bytes(b"not a model")
    from signlane.signs.classifier import DEFAULT_MODEL as SIGNS
    for path, words in ((tmp_path / "none.onnx", "not found"), (bad, "not a loadable"), (SIGNS, "lane-segmentation")):
        with pytest.raises(ModelError, match=words):
            seg_model.LaneSegModel(path)
    assert main(["eval", "masks", str(tmp_path), "--model", str(bad)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "bad.onnx" in err[0]


def test_infer_segnet_writes_its_mask_and_survives_bad_inputs(tmp_path, capsys):
    smp = FrameSampler(3, SamplerConfig(effects="clean", randomise=False)).sample(0)
    cv2.imwrite(str(tmp_path / "good.png"), smp.image)
    (tmp_path / "empty.jpg").write_bytes(b"")
    (tmp_path / "junk.png").write_bytes(b"\x89PNG junk")
    out = tmp_path / "out"
    code = main(["infer", "--no-progress", "--lanes", "segnet", str(tmp_path / "good.png"), str(tmp_path / "empty.jpg"),
                 str(tmp_path / "junk.png"), "--out", str(out), "--save-masks", "--json", "-"])
    stdout, err = capsys.readouterr()
    assert code == 1
    recs = [json.loads(line) for line in stdout.splitlines()]
    assert len(recs) == 1 and recs[0]["lane"]["method"] == "segnet" and recs[0]["lane"]["found"]
    assert sum("empty.jpg" in e or "junk.png" in e for e in err.splitlines()) == 2
    mask = cv2.imread(str(out / "good_lane.png"), cv2.IMREAD_UNCHANGED)
    f1 = MaskCounts()
    f1.add(mask, smp.truth.marking_mask)
    assert mask.shape == (240, 320) and f1.summary()["f1"] > 0.8


def test_config_picks_a_custom_segnet_model_and_rejects_one_for_a_classical_method(trained, tmp_path, capsys):
    _, _, _, onnx_path, _ = trained
    image = FrameSampler(3, SamplerConfig(effects="clean", randomise=False)).sample(0).image
    cv2.imwrite(str(tmp_path / "f.png"), image)
    args = ["infer", "--no-progress", str(tmp_path / "f.png"), "--json", "-"]
    assert main(args + ["--lanes", "segnet", "--set", f"lanes.model={onnx_path}"]) == 0
    assert json.loads(capsys.readouterr().out)["lane"]["method"] == "segnet"
    assert main(args + ["--lanes", "segnet", "--set", f"lanes.model={tmp_path / 'none.onnx'}"]) == 2
    assert main(args + ["--lanes", "canny-scan", "--set", f"lanes.model={onnx_path}"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and "none.onnx" in err[0] and "not found" in err[0] and "'model'" in err[1]


def test_shipped_model_meets_a_floor_on_a_fresh_seeded_set():
    """Floors well below the card's numbers (500+ frames) so 40 frames do not flake."""
    model = seg_model.LaneSegModel(seg_model.DEFAULT_MODEL)
    sampler = FrameSampler(4242, SamplerConfig(effects="normal"))
    counts, found, errs = MaskCounts(), 0, []
    for i in range(40):
        smp = sampler.sample(i)
        prob = model.probabilities([smp.image])[0]
        counts.add(seg_model.to_frame_mask(prob, 320, 240), smp.truth.marking_mask)
        est = lanes.get("segnet", camera=smp.truth.nominal_camera)(smp.image)
        found += est.found
        errs += [abs(est.offset - smp.truth.offset)] if est.found else []
    assert counts.summary()["f1"] >= 0.8
    assert found >= 34 and np.median(errs) < 0.08


def test_infer_segnet_sharpens_its_mask_on_a_large_frame(tmp_path, capsys):
    # at 640x480 one cell of the model's 160x120 map spans 4 pixels: the written mask is the
    # band brought up to the frame, narrowed to the frame's own paint (lanes/sharp_marking.py)
    sampler = FrameSampler(3, SamplerConfig(640, 480, effects="clean", randomise=False))
    model = seg_model.LaneSegModel(seg_model.DEFAULT_MODEL)
    band, sharp = MaskCounts(), MaskCounts()
    for i in range(3):
        smp = sampler.sample(i)
        cv2.imwrite(str(tmp_path / f"f{i}.png"), smp.image)
        assert main(["infer", "--no-progress", "--lanes", "segnet", str(tmp_path / f"f{i}.png"), "--out",
                     str(tmp_path / "out"), "--save-masks"]) == 0
        written = cv2.imread(str(tmp_path / "out" / f"f{i}_lane.png"), cv2.IMREAD_UNCHANGED)
        coarse = seg_model.to_frame_mask(model.probabilities([smp.image])[0], 640, 480)
        assert written.shape == (480, 640) and np.count_nonzero(written & ~coarse) == 0
        band.add(coarse, smp.truth.marking_mask)
        sharp.add(written, smp.truth.marking_mask)
    b, s = band.summary(), sharp.summary()
    assert s["precision"] > b["precision"] + 0.05 and s["recall"] > b["recall"] - 0.03
    capsys.readouterr()
