"""Lane-dataset label masks as class ids (0 background, 1 the class, 255 ignore): what the
generators write, old 0/255 sets reading as the same targets, and 255 left out of the loss, the
training metrics and `eval masks`. Tiny datasets (a few frames)."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest

from signlane import label_masks
from signlane.eval_masks import MaskCounts, eval_masks
from signlane.lanes.seg_model import mask_target

N = 4


@pytest.fixture(scope="module")
def generated(tmp_path_factory) -> Path:
    """A lane dataset as `signlane gen lanes` writes it now, with drivable masks."""
    from signlane_data.lanes import generate_lanes
    out = tmp_path_factory.mktemp("masks") / "new"
    generate_lanes(out, N, seed=3, drivable=True)
    return out


@pytest.fixture(scope="module")
def new_set(generated, tmp_path_factory) -> Path:
    """`generated` with its unseen paint (255: signlane.paint_visibility) made background, so that
    an old binary set made from it (which cannot say "no label") holds the same labels."""
    out = tmp_path_factory.mktemp("masks") / "plain"
    shutil.copytree(generated, out)
    for p in (out / "masks").glob("*.png"):
        m = cv2.imread(str(p), cv2.IMREAD_UNCHANGED)
        m[m == label_masks.IGNORE] = 0
        cv2.imwrite(str(p), m)
    return out


def as_old_set(new: Path, dst: Path, manifest: bool = True) -> Path:
    """`new` as a dataset made before the ids encoding: masks 0/255, no mask_encoding key (or,
    with manifest=False, no manifest at all: a folder made by hand)."""
    shutil.copytree(new, dst)
    for sub in ("masks", "drivable"):
        for p in (dst / sub).glob("*.png"):
            cv2.imwrite(str(p), (cv2.imread(str(p), cv2.IMREAD_UNCHANGED) > 0).astype(np.uint8) * 255)
    m = json.loads((dst / "manifest.json").read_text())
    del m["mask_encoding"], m["config"]["mask_encoding"]
    (dst / "manifest.json").write_text(json.dumps(m))
    if not manifest:
        (dst / "manifest.json").unlink()
        (dst / "labels.jsonl").unlink()
    return dst


def rows(root: Path) -> list[dict]:
    return [json.loads(line) for line in (root / "labels.jsonl").read_text().splitlines()]


# --------------------------------------------------------------------------- writing
def test_generator_writes_class_ids_and_records_the_encoding(generated):
    manifest = json.loads((generated / "manifest.json").read_text())
    assert manifest["mask_encoding"] == label_masks.IDS == "ids-0-1-255ignore"
    assert label_masks.dataset_encoding(generated) == label_masks.IDS
    painted, paint, unseen = 0, 0, 0
    for r in rows(generated):
        # painted style: no kerbs, so the marking masks' only 255s are paint the frame does not show
        for key, ids in (("mask", {0, 1, 255}), ("drivable", {0, 1})):
            m = cv2.imread(str(generated / r[key]), cv2.IMREAD_UNCHANGED)
            assert m.dtype == np.uint8 and m.shape == (240, 320) and set(np.unique(m)) <= ids
        m = cv2.imread(str(generated / r["mask"]), 0)
        painted += (m == 1).any()
        paint, unseen = paint + int((m == 1).sum()), unseen + int((m == 255).sum())
        assert (cv2.imread(str(generated / r["drivable"]), 0) == 1).mean() > 0.05  # the road ahead
    assert painted >= N // 2
    assert unseen < 0.05 * paint  # most paint is in view: only a little is left unlabelled


def test_encode_decode_and_bad_encodings(tmp_path):
    on = np.array([[1, 0, 0, 1]], bool)
    unknown = np.array([[1, 1, 0, 0]], bool)
    ids = label_masks.encode(on, unknown)
    assert ids.tolist() == [[1, 255, 0, 1]]  # a pixel of the class keeps its 1
    assert label_masks.decode(ids, label_masks.IDS).tolist() == [[1, 255, 0, 1]]
    assert label_masks.decode(np.array([[0, 255, 7]], np.uint8), label_masks.BINARY).tolist() == [[0, 1, 1]]
    with pytest.raises(ValueError, match="value 7"):
        label_masks.decode(np.array([[0, 7]], np.uint8), label_masks.IDS, "m.png")
    with pytest.raises(ValueError, match="m.png: holds 1s and 255s.*add"):  # ids in a folder that does not say so
        label_masks.decode(ids, label_masks.BINARY, "m.png")
    assert label_masks.dataset_encoding(tmp_path) == label_masks.BINARY  # no manifest: made by hand
    (tmp_path / "manifest.json").write_text(json.dumps({"mask_encoding": "rgb-palette"}))
    with pytest.raises(ValueError, match="rgb-palette"):
        label_masks.dataset_encoding(tmp_path)


def test_autolabel_marks_the_rows_beyond_its_paint_unknown():
    from signlane_data.autolabel_lanes import pseudo_mask
    debug = np.zeros((240, 320), np.uint8)
    debug[150:240, 100:104] = 255  # the paint a method followed: up to row 150
    ids = pseudo_mask(debug)
    assert (ids[:150] == 255).all() and (ids[150:, 100:104] == 1).all()
    assert set(np.unique(ids[150:])) == {0, 1}
    assert set(np.unique(pseudo_mask(np.zeros((8, 8), np.uint8)))) == {0}  # nothing labelled: nothing ignored


# --------------------------------------------------------------------------- reading
def test_old_binary_sets_give_the_same_training_targets(new_set, tmp_path):
    from signlane.lanes.seg_model import DEFAULT_SPEC
    from signlane_train.lane_data import FrameDataset, list_frames, train_augment
    old = as_old_set(new_set, tmp_path / "old")
    hand = as_old_set(new_set, tmp_path / "hand", manifest=False)
    assert set(np.unique(cv2.imread(str(old / "masks" / "000000.png"), 0))) == {0, 255}
    sets = [list_frames([root]) for root in (new_set, old, hand)]
    assert [s[0].encoding for s in sets] == [label_masks.IDS, label_masks.BINARY, label_masks.BINARY]
    for augment in (None, 11):  # plain, and through the same seeded augmentation
        data = [FrameDataset(s, DEFAULT_SPEC, None if augment is None else train_augment(augment)) for s in sets]
        for i in range(N):
            (x0, y0), *others = [d[i] for d in data]
            assert set(np.unique(y0.numpy())) <= ({0, 1} if augment is None else {0, 1, 255})
            for x, y in others:
                assert np.array_equal(x.numpy(), x0.numpy()) and np.array_equal(y.numpy(), y0.numpy())


def test_targets_keep_ignore_only_where_it_decides():
    ids = np.zeros((8, 8), np.uint8)
    ids[0:4, 0:4] = 1  # cell (0, 0): paint, whatever is ignored
    ids[0:4, 4:8] = 255  # cell (0, 1): no label at all
    ids[4, 4] = 1  # cell (1, 1): 1 of 16 paint, 1 ignored: even both cannot reach 25%
    ids[4, 5] = 255
    ids[4:6, 0:2] = 255  # cell (1, 0): 4 of 16 unknown could be 25% paint
    got = mask_target(ids == 1, (2, 2), ignore=ids == 255)
    assert got.tolist() == [[1, 255], [255, 0]]
    assert mask_target(ids == 1, (2, 2)).tolist() == [[1, 0], [0, 0]]  # no ignore given: no 255


def test_warps_pad_with_ignore():
    import albumentations as A
    from signlane_train.lane_data import train_augment
    warps = [t for t in train_augment(0).transforms if isinstance(t, (A.Affine, A.Perspective))]
    assert len(warps) == 2 and all(t.fill_mask == label_masks.IGNORE for t in warps)


# --------------------------------------------------------------------------- loss and metrics
def test_the_loss_ignores_255():
    import torch
    import torch.nn.functional as F
    from signlane_train.lane_task import LaneTask, dice_loss, weighted_ce
    task = LaneTask(width=4)
    torch.manual_seed(0)
    logits = torch.randn(2, 2, 6, 8, requires_grad=True)
    y = (torch.rand(2, 6, 8) > 0.7).long()
    # nothing ignored: the weighted cross-entropy is torch's own mean
    ce = F.cross_entropy(logits, y, weight=task.ce_weight)
    assert weighted_ce(logits, y, task.ce_weight).item() == pytest.approx(ce.item(), rel=1e-6)
    # all ignored: zero loss, zero gradient (torch's mean would be NaN)
    loss = task._loss(logits, torch.full_like(y, 255))
    loss.backward()
    assert loss.item() == 0.0 and float(logits.grad.abs().max()) == 0.0
    # an ignored pixel: changing its logits or its target value elsewhere changes nothing
    y2 = y.clone()
    y2[:, :2] = 255
    base = task._loss(logits, y2).item()
    moved = logits.detach().clone()
    moved[:, :, :2] += torch.randn(2, 2, 2, 8) * 5
    assert float(task._loss(moved, y2)) == pytest.approx(base, rel=1e-6)
    logits.grad = None
    task._loss(logits, y2).backward()
    assert float(logits.grad[:, :, :2].abs().max()) == 0.0 and float(logits.grad[:, :, 2:].abs().max()) > 0
    assert dice_loss(logits, y2).item() == pytest.approx(dice_loss(logits[:, :, 2:], y[:, 2:]).item(), rel=1e-6)


def test_training_metrics_skip_255():
    import torch
    from signlane_train.lane_task import LaneTask
    task = LaneTask(width=4)
    pred = torch.tensor([[1, 1, 0, 0, 1, 0]])
    y = torch.tensor([[1, 0, 0, 1, 255, 255]])
    task.val_iou.update(pred, y)
    assert float(task.val_iou.compute()) == pytest.approx(1 / 3)  # the 255s count nowhere
    task.val_iou.reset()
    task.val_iou.update(pred[:, :4], y[:, :4])
    assert float(task.val_iou.compute()) == pytest.approx(1 / 3)


def test_mask_counts_skip_ignored_pixels():
    pred = np.zeros((20, 20), np.uint8)
    true = np.zeros((20, 20), bool)
    true[:, 5] = True
    pred[:, 5] = 255
    pred[:, 15] = 255  # a false line ...
    ignore = np.zeros((20, 20), bool)
    ignore[:, 12:] = True  # ... where nothing is labelled
    a, b = MaskCounts(), MaskCounts()
    a.add(pred, true, 1)
    b.add(pred, true, 1, ignore)
    assert a.summary()["precision"] == pytest.approx(0.5) and a.iou == pytest.approx(0.5)
    assert b.summary()["precision"] == 1.0 and b.summary()["f1"] == 1.0 and b.iou == 1.0


def test_eval_masks_reads_both_encodings_and_skips_255(new_set, tmp_path):
    ref = eval_masks(new_set, progress=False)
    old = eval_masks(as_old_set(new_set, tmp_path / "old"), progress=False)
    assert ref["mask_encoding"] == label_masks.IDS and old["mask_encoding"] == label_masks.BINARY
    scores = ("precision", "recall", "f1", "iou")
    assert [old[k] for k in scores] == [ref[k] for k in scores] and 0 < ref["iou"] <= 1
    # frame 0 without any label counts as if it were not there
    blank = tmp_path / "blank"
    shutil.copytree(new_set, blank)
    first = rows(blank)[0]
    cv2.imwrite(str(blank / first["mask"]), np.full((240, 320), 255, np.uint8))
    less = tmp_path / "less"
    shutil.copytree(new_set, less)
    (less / "labels.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows(new_set)[1:]))
    got, want = eval_masks(blank, progress=False), eval_masks(less, progress=False)
    assert [got[k] for k in scores] == [want[k] for k in scores]
    assert got["frames"] == N and want["frames"] == N - 1
