"""A road model, not only a paint model: drivable-area truth and targets, a road model trained,
exported and loaded beside the old marking-only contract, infer's drivable masks, segnet's lane
from the drivable area's edges, and autolabel's road pseudo-labels."""
import json

import cv2
import numpy as np
import onnx
import pytest

from signlane import lanes
from signlane.camera import via_camera
from signlane.cli import main
from signlane.config import CameraConfig
from signlane.label_masks import IGNORE
from signlane.lanes import seg_model
from signlane.lanes.road_edges import RoadEdgesParams, RoadEdgesState
from signlane.lanes.seg_model import FrameMaps, output_to_frame
from signlane.lanes.segnet import edges_lane
from signlane.world.sampling import FrameSampler, SamplerConfig


@pytest.fixture(scope="module")
def road_model(tmp_path_factory):
    """Mixed-style heavy frames with road masks and an autolabelled folder, 1 epoch, exported."""
    from signlane_data.autolabel_lanes import autolabel_lanes
    from signlane_data.lanes import generate_lanes
    from signlane_export.lanes import export_lanes
    from signlane_train.lanes import train_lanes
    root = tmp_path_factory.mktemp("road")
    generate_lanes(root / "mixed", 24, seed=6, preset="heavy", style="mixed", drivable=True)
    photos = root / "photos"
    photos.mkdir()
    smp = FrameSampler(4, SamplerConfig(effects="clean", randomise=False, style="via"))
    samples = [smp.sample(i) for i in range(0, 12, 2)]
    for i, s in enumerate(samples):
        cv2.imwrite(str(photos / f"v{i}.png"), s.image)
    auto = autolabel_lanes([str(photos)], root / "auto", method="road-edges", camera=CameraConfig(), progress=False)
    report = train_lanes([root / "mixed", root / "auto"], root / "run", epochs=1, batch_size=8, workers=0,
                         quiet=True, eval_frames=8, threads=1)
    onnx_path = root / "road.onnx"
    exported = export_lanes(report["best_checkpoint"], onnx_path)
    return root, samples, auto, report, onnx_path, exported


@pytest.fixture(scope="module")
def marking_model(tmp_path_factory):
    """A marking-only model (the contract before road models), trained 1 epoch on frames
    without road masks and exported."""
    from signlane_data.lanes import generate_lanes
    from signlane_export.lanes import export_lanes
    from signlane_train.lanes import train_lanes
    root = tmp_path_factory.mktemp("paint")
    generate_lanes(root / "paint", 24, seed=6)
    report = train_lanes([root / "paint"], root / "run", epochs=1, batch_size=8, workers=0, quiet=True,
                         eval_frames=4, threads=1)
    path = root / "paint.onnx"
    export_lanes(report["best_checkpoint"], path)
    return path


def test_drivable_target_is_the_labelled_majority_of_each_cell():
    from signlane_train.lane_data import drivable_target
    road = np.zeros((8, 8), np.uint8)
    road[:, 4:] = 1  # right half road
    road[0:4, 0:2] = IGNORE  # a corner without a label
    t = drivable_target(road, (4, 4))
    assert t.tolist() == [[IGNORE, 0, 1, 1], [IGNORE, 0, 1, 1], [0, 0, 1, 1], [0, 0, 1, 1]]


def test_road_model_exports_its_two_heads_and_the_old_contract_still_loads(road_model, marking_model):
    root, _, _, report, onnx_path, exported = road_model
    assert exported["parity_max_abs"] <= 1e-4 and report["parameters"] <= 500_000
    assert 0.0 <= report["val_drivable_iou"] <= 1.0
    meta = {p.key: p.value for p in onnx.load(str(onnx_path)).metadata_props}
    assert json.loads(meta["signlane.classes"]) == list(seg_model.ROAD_CLASSES)
    assert json.loads(meta["signlane.output"])["heads"] == {"lane_marking": [0, 1], "drivable": [2, 3]}
    model = seg_model.LaneSegModel(onnx_path)
    frames = [cv2.imread(str(p)) for p in sorted((root / "mixed" / "images").glob("*.jpg"))[:3]]
    marking, road = model.maps(frames)
    assert model.has_drivable and marking.shape == road.shape == (3, 120, 160)
    assert np.array_equal(marking, model.probabilities(frames))
    old = seg_model.LaneSegModel(marking_model)  # a marking-only file
    m, r = old.maps(frames)
    assert not old.has_drivable and r is None and m.shape == (3, 120, 160)


def test_training_mixes_sets_with_and_without_road_masks(road_model):
    from signlane_train.lane_data import FrameDataset, list_frames
    root = road_model[0]
    items = list_frames([root / "mixed", root / "auto"])
    with_road = [it for it in items if it.drivable is not None]
    assert {it.key.split("/")[0] for it in with_road} >= {"mixed"}
    no_road = [it for it in items if it.drivable is None]
    if no_road:  # autolabel frames road-edges was not confident about: no road label, all ignored
        _, _, d = FrameDataset(no_road[:1], seg_model.DEFAULT_SPEC, drivable=True)[0]
        assert (d == IGNORE).all()
    _, _, d = FrameDataset(with_road[:1], seg_model.DEFAULT_SPEC, drivable=True)[0]
    d = d.numpy()
    # labelled but for kerbs (VIA style) and what the augmentation's warp pads in
    assert set(np.unique(d)) <= {0, 1, IGNORE} and d.shape == (120, 160) and (d != IGNORE).mean() > 0.8


def test_eval_masks_scores_the_drivable_area(road_model, marking_model):
    from signlane.eval_masks import eval_masks
    root, _, _, _, onnx_path, _ = road_model
    out = eval_masks(root / "mixed", onnx_path, progress=False)
    assert out["drivable_frames"] == 24 and 0.0 <= out["drivable_iou"] <= 1.0
    assert "drivable_iou" not in eval_masks(root / "mixed", marking_model, progress=False)  # a marking model has none
    assert "drivable_iou" in eval_masks(root / "mixed", None, progress=False)  # the shipped model is a road model


def test_infer_writes_drivable_masks_where_the_model_has_a_road_output(road_model, marking_model, tmp_path, capsys):
    _, samples, _, _, onnx_path, _ = road_model
    cv2.imwrite(str(tmp_path / "f.png"), samples[0].image)
    out = tmp_path / "out"
    assert main(["infer", "--no-progress", "--lanes", "segnet", "--set", f"lanes.model={onnx_path}",
                 str(tmp_path / "f.png"), "--out", str(out), "--save-masks"]) == 0
    road = cv2.imread(str(out / "f_drivable.png"), cv2.IMREAD_UNCHANGED)
    assert road.shape == (240, 320) and road.dtype == np.uint8 and set(np.unique(road)) <= {0, 255}
    out2 = tmp_path / "out2"  # a marking-only model: no road output, no file
    assert main(["infer", "--no-progress", "--lanes", "segnet", "--set", f"lanes.model={marking_model}",
                 str(tmp_path / "f.png"), "--out", str(out2), "--save-masks"]) == 0
    assert (out2 / "f_lane.png").exists() and not (out2 / "f_drivable.png").exists()
    capsys.readouterr()


@pytest.mark.parametrize("i", [0, 2, 4])
def test_segnet_keeps_the_middle_of_the_drivable_area_where_there_is_no_paint(road_model, i):
    """VIA's kerbed road has no paint: given its true road surface as the network's P(road),
    the lane is the carriageway between its edges and the offset is the truth's."""
    smp = road_model[1][i]
    prob = (smp.truth.drivable_mask > 0).astype(np.float32)
    h, w = prob.shape
    cam = via_camera(w, h)
    maps = FrameMaps(np.zeros_like(prob), prob, output_to_frame(prob.shape, w, h))
    est, state = edges_lane("segnet", smp.image, cam, RoadEdgesParams(), RoadEdgesState(), maps)
    assert est.found and est.basis == "edges"
    assert np.array_equal(est.drivable_mask > 0, smp.truth.drivable_mask > 0)  # the model's road, at the frame's size
    assert abs(est.offset - smp.truth.offset) < 0.1, (est.offset, smp.truth.offset)
    assert state.scan is not None


def test_autolabel_writes_road_masks_that_match_the_truth(road_model):
    """road-edges' confident frames of VIA's road: where the pseudo-label says road or not road,
    the renderer agrees on nearly every pixel."""
    root, samples, auto, *_ = road_model
    recs = [json.loads(line) for line in (root / "auto" / "labels.jsonl").read_text().splitlines()]
    assert auto["counts"]["drivable"] >= 3 and sum("drivable" in r for r in recs) == auto["counts"]["drivable"]
    by_name = {f"v{i}": s for i, s in enumerate(samples)}
    for rec in recs:
        if "drivable" not in rec:
            continue
        ids = cv2.imread(str(root / "auto" / rec["drivable"]), cv2.IMREAD_UNCHANGED)
        truth = by_name[rec["id"].rsplit("_", 1)[0]].truth.drivable_mask > 0
        labelled = ids != IGNORE
        assert labelled.mean() > 0.2 and set(np.unique(ids)) <= {0, 1, IGNORE}
        assert ((ids == 1) == truth)[labelled].mean() > 0.95


def test_segnet_edges_keep_the_right_half_of_a_road_with_a_centre_line():
    """A painted two-lane road given as the network's maps (its true road and paint) but with no
    paint lane found: over a few frames the middle shows the centre line, and the lane is the
    right half of the carriageway, the truth's ego lane."""
    from signlane.camera import Camera
    from signlane.world.sampling import DriveSampler
    d = DriveSampler(3, SamplerConfig(320, 240, effects="clean", randomise=False), fps=10, camera=Camera(320, 240))
    state, errors = RoadEdgesState(), []
    for i in range(12):
        smp = d.sample(i)
        road = (smp.truth.drivable_mask > 0).astype(np.float32)
        paint = (smp.truth.marking_mask > 0).astype(np.float32)
        maps = FrameMaps(paint, road, output_to_frame(road.shape, 320, 240))
        est, state = edges_lane("segnet", smp.image, d.camera, RoadEdgesParams(), state, maps)
        if i >= 6:
            errors.append(abs(est.offset - smp.truth.offset) if est.found else 1.0)
    assert state.two_lane and max(errors) < 0.15, errors


def test_auto_refuses_a_marking_only_model(marking_model, tmp_path, capsys):
    """A marking model cannot tell road from verge: auto refuses it in one line naming the file,
    for a frame as for a drive (`sim --with-driver` exits 2 before driving)."""
    from signlane.lanes.auto import AutoParams, auto
    from signlane.onnx_model import ModelError
    with pytest.raises(ModelError, match=r"paint\.onnx: a lane-marking model .*auto needs a road model"):
        auto(np.full((240, 320, 3), 100, np.uint8), via_camera(320, 240), AutoParams(model=str(marking_model)), None)
    assert main(["sim", "--with-driver", "--lockstep", "--no-web", "--max-seconds", "1", "--set",
                 f"lanes.model={marking_model}", "--out", str(tmp_path / "sim")]) == 2
    err = [line for line in capsys.readouterr().err.strip().splitlines() if "%|" not in line]  # not the progress bar
    assert len(err) == 1 and err[0].startswith("signlane sim: error: ") and "paint.onnx" in err[0], err
