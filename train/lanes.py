"""`signlane train lanes`: train the lane-marking segmentation net on synthetic and/or
pseudo-labelled lane sets; report marking F1 within 2 px at the frame's size on the val split."""
from __future__ import annotations

import json
import logging
from pathlib import Path

import torch

from signlane.eval_masks import MaskCounts, RoadCounts
from signlane.fileio import atomic_write_text
from signlane.label_masks import IGNORE
from signlane.lanes.seg_model import (DEFAULT_SPEC, drivable_probability, marking_probability, preprocess_frames,
                                     to_frame_mask)
from signlane.splits import VAL_FRACTION
from signlane_train.common import build_trainer, fit_best, resume_path, save_run_config
from signlane_train.lane_data import FrameDataset, LaneDataModule, read_drivable, read_pair
from signlane_train.lane_net import count_parameters
from signlane_train.lane_task import LaneTask
from signlane_train.run_info import RunInfo

log = logging.getLogger(__name__)


def train_lanes(data: list[str | Path], out: str | Path, epochs: int = 15, batch_size: int = 32, lr: float = 4e-3,
                width: int = 16, val_fraction: float = VAL_FRACTION, patience: int = 5, seed: int = 0, resume: bool = False,
                trainer_args: dict | None = None, workers: int = 1, quiet: bool = False, pos_weight: float = 4.0,
                eval_frames: int = 300, threads: int = 0, deterministic: bool = True, scene: bool = True,
                drivable_dice: float = 0.5) -> dict:
    """Train; writes checkpoints/, logs/, tensorboard/, samples/epoch_<k>.png, config.json and
    report.json (the best checkpoint's val scores).
    threads > 0 caps torch's CPU threads: on a busy machine one thread trains several times faster
    than threads that wait for each other on shared cores. deterministic (the default) asks torch
    for deterministic algorithms, so the same seed repeats a run exactly (on GPUs too). Every
    checkpoint carries the data's content hash and its validation scores, for export."""
    import lightning as L
    out = Path(out)
    if threads > 0:
        torch.set_num_threads(threads)
    ckpt_path = resume_path(out, resume)
    L.seed_everything(seed, workers=True)
    dm = LaneDataModule(data, batch_size, val_fraction, DEFAULT_SPEC, workers, seed)
    dm.setup()
    task = LaneTask(width=width, lr=lr, pos_weight=pos_weight, input_size=(DEFAULT_SPEC.width, DEFAULT_SPEC.height),
                    drivable=dm.drivable, scene=scene, drivable_dice=drivable_dice)
    task.samples_dir = out / "samples"
    val = FrameDataset(dm.val_items[:8], DEFAULT_SPEC)
    task.sample_batch = (torch.stack([val[i][0] for i in range(len(val))]),
                         torch.stack([val[i][1] for i in range(len(val))]))
    info = RunInfo(data)
    save_run_config(out, {"task": "lanes", "data": info.data, "data_hash": info.data_hash, "epochs": epochs,
                          "batch_size": batch_size, "lr": lr, "width": width, "pos_weight": pos_weight,
                          "scene": scene, "drivable_dice": drivable_dice,
                          "val_fraction": val_fraction, "seed": seed, "deterministic": deterministic,
                          "input": [DEFAULT_SPEC.width, DEFAULT_SPEC.height],
                          "parameters": count_parameters(task.net), "train_frames": len(dm.train_items),
                          "val_frames": len(dm.val_items), "threads": threads, "drivable": dm.drivable,
                          "trainer": trainer_args or {}})
    trainer, ckpt = build_trainer(out, epochs, "val/iou", "max", patience, trainer_args, [info], quiet=quiet,
                                  deterministic=deterministic)
    best, seconds = fit_best(trainer, ckpt, task, dm, out, ckpt_path)
    report = evaluate_checkpoint(best, dm.val_items[:eval_frames])
    report.update({"best_checkpoint": best, "train_seconds": round(seconds, 1),
                   "parameters": count_parameters(task.net)})
    atomic_write_text(out / "report.json", json.dumps(report, indent=1))  # export puts it in the metadata
    return report


def evaluate_checkpoint(ckpt: str, items, tol: int = 2) -> dict:
    """Marking precision/recall/F1 within tol px at each frame's own size, through the runtime's
    pre- and post-processing (the numbers the exported model will give); pixels without a label
    (mask ids 255) count nowhere. A road model adds the drivable IoU over the frames with a road
    mask (val_drivable_iou)."""
    task = LaneTask.load_from_checkpoint(ckpt, map_location="cpu").eval()
    counts = MaskCounts()
    road = RoadCounts()
    with torch.no_grad():
        for i in range(0, len(items), 32):
            chunk = items[i:i + 32]
            pairs = [read_pair(it) for it in chunk]
            x = torch.from_numpy(preprocess_frames([p[0] for p in pairs], DEFAULT_SPEC))
            logits = task(x).numpy()
            prob = marking_probability(logits)
            for (img, mask), pr in zip(pairs, prob):
                counts.add(to_frame_mask(pr, img.shape[1], img.shape[0]), mask == 1, tol, mask == IGNORE)
            if logits.shape[1] == 4:
                for it, (img, mask), pr in zip(chunk, pairs, drivable_probability(logits)):
                    if it.drivable is not None:
                        road.add(to_frame_mask(pr, img.shape[1], img.shape[0]), read_drivable(it, mask.shape))
    out = {f"val_{k}_at_{tol}px" if k != "frames" else "val_frames": v for k, v in counts.summary().items()}
    if road.frames:
        out["val_drivable_iou"] = road.iou
    return out
