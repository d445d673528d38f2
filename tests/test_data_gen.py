"""Dataset generators (data_gen): determinism across workers, resume, the label contract, the
sign ImageFolder, the drive video and the previews. Small n and small images keep it fast."""
from __future__ import annotations

import hashlib
import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from gen_helpers import generate_lanes_killed_at
from signlane_data.common import (DatasetError, atomic_write_bytes, chunked, prepare_output, run_indexed, sample_id)
from signlane_data.drive import generate_drive
from signlane_data.lanes import generate_lanes, teacher_steering
from signlane.draw import contact_sheet
from signlane_data.sign_crops import colour_regions, crop_resize, iou, jitter_box
from signlane_data.signs import class_targets, generate_signs, unknown_quota
from signlane.world.art import SIGN_CLASSES, draw_sign

N_LANES = 12
LANE_KW = dict(width=160, height=120)  # small frames: the contract does not depend on size


def tree_hashes(root: Path) -> dict[str, str]:
    """sha1 of every file under root, keyed by relative path; the manifest without `created`."""
    out = {}
    for p in sorted(root.rglob("*")):
        if p.is_file():
            data = p.read_bytes()
            if p.name == "manifest.json":
                m = json.loads(data)
                m.pop("created")
                data = json.dumps(m, sort_keys=True).encode()
            out[str(p.relative_to(root))] = hashlib.sha1(data).hexdigest()
    return out


@pytest.fixture(scope="module")
def lanes_ref(tmp_path_factory) -> Path:
    """An uninterrupted single-worker lane dataset, with a preview."""
    out = tmp_path_factory.mktemp("lanes") / "ref"
    generate_lanes(out, N_LANES, seed=7, workers=1, preview=True, **LANE_KW)
    return out


# --------------------------------------------------------------------------- common
def test_chunks_stay_inside_track_groups() -> None:
    assert chunked([0, 1, 2, 3, 4, 5, 6], 3) == [[0, 1, 2], [3, 4, 5], [6]]
    assert chunked([1, 2, 4, 5, 6, 9], 3) == [[1, 2], [4, 5], [6], [9]]


def test_run_indexed_skips_done(tmp_path: Path) -> None:
    done = {1, 3}
    got = run_indexed(5, str, workers=1, done_fn=done.__contains__)
    assert got == {0: "0", 2: "2", 4: "4"}


def test_atomic_write_leaves_no_temporary(tmp_path: Path) -> None:
    atomic_write_bytes(tmp_path / "a.bin", b"xyz")
    assert [p.name for p in tmp_path.iterdir()] == ["a.bin"]
    assert (tmp_path / "a.bin").read_bytes() == b"xyz"


def test_sample_ids_sort_in_order() -> None:
    assert sample_id(123, 10) == "000123"
    assert sample_id(5, 2_000_000) == "0000005"


def test_non_empty_folder_needs_resume(tmp_path: Path) -> None:
    (tmp_path / "something.txt").write_text("not a dataset")
    with pytest.raises(DatasetError, match="--resume"):
        prepare_output(tmp_path, "lanes", {"n": 1}, resume=False)


# --------------------------------------------------------------------------- lanes
def test_lanes_identical_with_two_workers(lanes_ref: Path, tmp_path: Path) -> None:
    generate_lanes(tmp_path / "w2", N_LANES, seed=7, workers=2, **LANE_KW)
    ref, two = tree_hashes(lanes_ref), tree_hashes(tmp_path / "w2")
    ref.pop("preview.png")
    assert two == ref


def test_lanes_labels_follow_the_contract(lanes_ref: Path) -> None:
    rows = [json.loads(line) for line in (lanes_ref / "labels.jsonl").read_text().splitlines()]
    assert [r["id"] for r in rows] == [sample_id(i, N_LANES) for i in range(N_LANES)]
    paint = unseen = 0
    for r in rows:
        assert {"id", "image", "mask", "width", "height", "lane", "signs", "steering"} <= set(r)
        assert {"left", "right", "center", "offset", "heading", "curvature"} <= set(r["lane"])
        assert r["image"] == f"images/{r['id']}.jpg" and r["mask"] == f"masks/{r['id']}.png"
        img = cv2.imread(str(lanes_ref / r["image"]), cv2.IMREAD_UNCHANGED)
        mask = cv2.imread(str(lanes_ref / r["mask"]), cv2.IMREAD_UNCHANGED)
        assert img.shape == (r["height"], r["width"], 3) == (120, 160, 3)
        assert mask.dtype == np.uint8 and mask.shape == img.shape[:2]
        assert set(np.unique(mask)) <= {0, 1, 255}  # class ids; 255: paint the frame does not show
        paint, unseen = paint + int((mask == 1).sum()), unseen + int((mask == 255).sum())
        for key in ("left", "right", "center"):
            pts = np.asarray(r["lane"][key], float).reshape(-1, 2)
            assert np.all((pts >= 0) & (pts <= [r["width"] - 1, r["height"] - 1])), (r["id"], key)
        assert -1.0 <= r["steering"] <= 1.0
        lane = r["lane"]  # the label rounds the pose, so the recomputed steering differs a little
        assert r["steering"] == pytest.approx(teacher_steering(lane["offset"], lane["heading"], lane["curvature"]),
                                              abs=1e-3)
        for s in r["signs"]:
            assert s["label"] in SIGN_CLASSES and len(s["box"]) == 4 and s["distance"] > 0
    assert sum((cv2.imread(str(lanes_ref / r["mask"]), 0) == 1).any() for r in rows) >= N_LANES // 2
    assert paint > 0 and unseen < 0.1 * paint  # most of the paint is in view and labelled
    manifest = json.loads((lanes_ref / "manifest.json").read_text())
    assert manifest["generator"] == "signlane.data_gen.lanes" and manifest["counts"]["frames"] == N_LANES
    assert manifest["seed"] == 7 and manifest["config"]["sampler"]["width"] == 160
    assert manifest["mask_encoding"] == "ids-0-1-255ignore"
    assert not (lanes_ref / ".partial").exists()


def test_teacher_steering_signs() -> None:
    assert teacher_steering(0.3, 0.0, 0.0) < 0  # right of centre: steer left
    assert teacher_steering(-0.3, 0.0, 0.0) > 0
    assert teacher_steering(0.0, 0.1, 0.0) < 0  # pointing right: steer left
    assert teacher_steering(0.0, 0.0, 0.05) > 0  # road bends right: steer right
    assert teacher_steering(5.0, 1.0, 0.0) == -1.0


def test_lanes_resume_after_interruption(lanes_ref: Path, tmp_path: Path, monkeypatch) -> None:
    out = tmp_path / "killed"
    generate_lanes_killed_at(out, 7, monkeypatch, N_LANES, seed=7, **LANE_KW)
    assert not (out / "manifest.json").exists()
    (out / "images" / "000003.jpg").unlink()
    (out / "masks" / ".000005.png.999.tmp").write_bytes(b"half a png")
    (out / "images" / "000004.jpg.tmp").write_bytes(b"half a jpg")
    with pytest.raises(DatasetError, match="--resume"):
        generate_lanes(out, N_LANES, seed=7, **LANE_KW)
    with pytest.raises(DatasetError, match="different options"):
        generate_lanes(out, N_LANES, seed=8, resume=True, **LANE_KW)
    generate_lanes(out, N_LANES, seed=7, resume=True, **LANE_KW)
    ref = tree_hashes(lanes_ref)
    ref.pop("preview.png")
    assert tree_hashes(out) == ref


def test_lanes_resume_after_deleting_outputs(lanes_ref: Path, tmp_path: Path) -> None:
    out = tmp_path / "copy"
    generate_lanes(out, N_LANES, seed=7, **LANE_KW)
    (out / "manifest.json").unlink()
    (out / "masks" / "000002.png").unlink()
    (out / "labels.jsonl").write_text("truncated")
    (out / "images" / "000011.jpg.tmp").write_bytes(b"")
    generate_lanes(out, N_LANES, seed=7, resume=True, **LANE_KW)
    ref = tree_hashes(lanes_ref)
    ref.pop("preview.png")
    assert tree_hashes(out) == ref


def test_complete_dataset_is_left_alone(lanes_ref: Path) -> None:
    before = tree_hashes(lanes_ref)
    manifest = generate_lanes(lanes_ref, N_LANES, seed=7, **LANE_KW)  # same options: nothing to do
    assert manifest["counts"]["frames"] == N_LANES
    assert tree_hashes(lanes_ref) == before
    with pytest.raises(DatasetError, match="different options"):
        generate_lanes(lanes_ref, N_LANES + 1, seed=7, **LANE_KW)


def test_lane_preview_is_a_sheet(lanes_ref: Path) -> None:
    sheet = cv2.imread(str(lanes_ref / "preview.png"))
    assert sheet is not None and sheet.shape == (2 * 180, 8 * 240, 3)  # 12 frames, 8 a row
    assert sheet.std() > 10  # frames, not a blank canvas


# --------------------------------------------------------------------------- signs
def test_class_targets_and_quotas() -> None:
    t = class_targets(100, 0.3)
    assert sum(t.values()) == 100 and t["unknown"] == 28 and t["left"] == 12
    assert sum(unknown_quota(i, 7, 20) for i in range(7)) == 20


def test_crop_helpers() -> None:
    img = np.zeros((100, 100, 3), np.uint8)
    img[40:60, 40:60] = 255
    rng = np.random.default_rng(0)
    x0, y0, x1, y1 = jitter_box((40, 40, 20, 20), rng)
    assert 40 - 5 - 2 <= x0 <= 40 + 2 and 60 - 2 <= x1 <= 60 + 5 + 2
    crop = crop_resize(img, (-10, -10, 30, 30), 48)  # leaves the image: edge pixels repeat
    assert crop.shape == (48, 48, 3) and crop.dtype == np.uint8
    assert iou((0, 0, 10, 10), (5, 0, 10, 10)) == pytest.approx(1 / 3)
    scene = np.full((120, 160, 3), 90, np.uint8)
    face = draw_sign("stop", 30)
    scene[20:50, 30:60] = np.where(face[..., 3:] > 127, face[..., :3], scene[20:50, 30:60])
    boxes = colour_regions(scene)
    assert len(boxes) == 1 and iou(boxes[0], (30, 20, 30, 30)) > 0.7


def test_signs_imagefolder(tmp_path: Path) -> None:
    out = tmp_path / "signs"
    manifest = generate_signs(out, 70, seed=3, crop=32, preview=True)
    assert sorted(p.name for p in out.iterdir() if p.is_dir()) == sorted(SIGN_CLASSES)
    for c in SIGN_CLASSES:
        files = sorted((out / c).glob("*.png"))
        assert len(files) == manifest["counts"][c] > 0, c
        for p in files[:5] + files[-5:]:
            img = cv2.imread(str(p), cv2.IMREAD_UNCHANGED)
            assert img.shape == (32, 32, 3) and img.dtype == np.uint8
    assert manifest["counts"]["unknown"] >= class_targets(70, 0.3)["unknown"]
    assert manifest["sources"]["frames"]["unknown"] > 0  # real unknown crops from the frames
    assert sum(manifest["counts"].values()) >= 70
    assert cv2.imread(str(out / "preview.png")) is not None
    assert not (out / ".partial").exists()  # ImageFolder would take it for a class
    # the conventions: class index order, and train.txt / val.txt = the split training uses
    assert (out / "classes.txt").read_text().split() == list(SIGN_CLASSES) == manifest["class_order"]
    from signlane.splits import split_of
    train, val = ((out / f).read_text().split() for f in ("train.txt", "val.txt"))
    every = sorted(f"{c}/{p.name}" for c in SIGN_CLASSES for p in (out / c).glob("*.png"))
    assert sorted(train + val) == every and val and manifest["split"] == {"train": len(train), "val": len(val)}
    assert all(split_of(k) == "val" for k in val) and all(split_of(k) == "train" for k in train)


def test_signs_identical_with_two_workers(tmp_path: Path) -> None:
    a = generate_signs(tmp_path / "a", 40, seed=5, crop=24, workers=1, frames=10)
    b = generate_signs(tmp_path / "b", 40, seed=5, crop=24, workers=2, frames=10)
    assert a["counts"] == b["counts"]
    assert tree_hashes(tmp_path / "a") == tree_hashes(tmp_path / "b")


def test_every_world_distractor_is_an_unknown_sprite_and_no_octagon_is() -> None:
    from signlane_data.sign_crops import STOP_WORDS, UNKNOWN_KIND_WEIGHTS
    from signlane.world.art import DISTRACTOR_KINDS
    assert set(UNKNOWN_KIND_WEIGHTS) == set(DISTRACTOR_KINDS)  # what the car meets, the classifier met
    assert not any("octagon" in k for k in DISTRACTOR_KINDS)  # a red octagon is a stop sign
    assert sum(STOP_WORDS.values()) == pytest.approx(1.0) and max(STOP_WORDS, key=STOP_WORDS.get) == "STOP"


# --------------------------------------------------------------------------- drive
def test_drive_frames_and_video(tmp_path: Path) -> None:
    out = tmp_path / "drive"
    manifest = generate_drive(out, 10, seed=2, width=160, height=120, fps=10)
    rows = [json.loads(line) for line in (out / "labels.jsonl").read_text().splitlines()]
    assert [r["t"] for r in rows] == pytest.approx([i / 10 for i in range(10)])
    xy = np.array([[r["pose"]["x"], r["pose"]["y"]] for r in rows])
    step = np.hypot(*np.diff(xy, axis=0).T)
    # 0.8 m apart at 8 m/s and 10 fps (each pose snaps to the route's sample grid: not exactly)
    assert step.mean() == pytest.approx(0.8, rel=0.05) and np.all(np.abs(step - 0.8) < 0.3)
    cap = cv2.VideoCapture(str(out / "drive.mp4"))
    assert cap.isOpened()
    frames = 0
    while True:
        ok, frame = cap.read()
        if not ok:
            break
        assert frame.shape == (120, 160, 3)
        frames += 1
    cap.release()
    assert frames == 10 and manifest["counts"]["frames"] == 10
    assert manifest["mask_encoding"] == "ids-0-1-255ignore"
    assert set(np.unique(cv2.imread(str(out / rows[0]["mask"]), cv2.IMREAD_UNCHANGED))) <= {0, 1, 255}  # 255: kerbs
    import av
    with av.open(str(out / "drive.mp4")) as box:  # H.264, which browsers play (OpenCV reads it too)
        assert box.streams.video[0].codec_context.name == "h264" and manifest["config"]["video"] == "h264"


# --------------------------------------------------------------------------- preview
def test_contact_sheet_layout() -> None:
    imgs = [np.full((30, 40, 3), k * 20, np.uint8) for k in range(10)] + [np.zeros((10, 10), np.uint8)]
    sheet = contact_sheet(imgs, cols=4, tile=(80, 60), captions=[str(k) for k in range(11)], gap=0)
    assert sheet.shape == (3 * 60, 4 * 80, 3) and sheet.dtype == np.uint8


def test_kerbs_carry_no_label_in_either_mask(tmp_path: Path) -> None:
    """A VIA-style kerb is a white stripe beside the road: neither paint nor road surface, but
    labelled 0 it teaches a road model that white stripes on asphalt are off-road, so both masks
    leave its pixels unlabelled (255) and every other pixel keeps its class."""
    from signlane.world.sampling import FrameSampler, SamplerConfig
    from signlane_data.lanes import write_frame
    sampler = FrameSampler(3, SamplerConfig(width=160, height=120, style="via", effects="clean"))
    kerbs = 0
    for i in range(6):
        smp = sampler.sample(i)
        write_frame(tmp_path, f"{i:02d}", smp, drivable=True)
        kerb = smp.truth.kerb_mask > 0
        kerbs += int(kerb.sum())
        marking = cv2.imread(str(tmp_path / "masks" / f"{i:02d}.png"), 0)
        road = cv2.imread(str(tmp_path / "drivable" / f"{i:02d}.png"), 0)
        assert np.array_equal(marking == 255, kerb) and np.array_equal(road == 255, kerb)
        assert np.array_equal(marking == 1, smp.truth.marking_mask > 0)
        assert np.array_equal(road == 1, smp.truth.drivable_mask > 0)
    assert kerbs > 500  # the frames do show kerbs


def test_junction_share_is_recorded_only_when_used_and_checked(lanes_ref: Path, tmp_path: Path) -> None:
    """A set made without `junctions` keeps the manifest it always had (so sets made before the
    option still match their config); a set made with it records it; a share outside 0..1 is refused."""
    assert "junctions" not in json.loads((lanes_ref / "manifest.json").read_text())["config"]["sampler"]
    m = generate_lanes(tmp_path / "j", 4, seed=7, junctions=0.5, **LANE_KW)
    assert m["config"]["sampler"]["junctions"] == 0.5
    with pytest.raises(ValueError, match="share of the frames"):
        generate_lanes(tmp_path / "bad", 4, seed=7, junctions=1.5, **LANE_KW)
    with pytest.raises(DatasetError, match="different options"):
        generate_lanes(lanes_ref, N_LANES, seed=7, junctions=0.5, **LANE_KW)
