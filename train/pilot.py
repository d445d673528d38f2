"""`signlane train pilot`: the end-to-end pilot on the teacher's drive recordings; report the
best checkpoint's steering error on the val split (whole blocks of consecutive frames)."""
from __future__ import annotations

import json
import logging
from pathlib import Path

import numpy as np
import torch

from signlane.fileio import atomic_write_text
from signlane.pilot import DESIRES, PILOTNET_SPEC, SMALL_SPEC
from signlane.splits import VAL_FRACTION
from signlane_train.common import build_trainer, fit_best, resume_path, save_run_config
from signlane_train.pilot_data import AugmentParams, PilotDataModule, PilotDataset
from signlane_train.pilot_net import count_parameters
from signlane_train.pilot_task import PilotTask, pick_steering
from signlane_train.run_info import RunInfo

log = logging.getLogger(__name__)

# S3's recipe for PilotNet; ours trains with a higher rate (batch norm) and a larger batch
DEFAULTS = {"pilotnet": {"lr": 1e-4, "batch_size": 100, "schedule": "constant"},
            "small": {"lr": 2e-3, "batch_size": 128, "schedule": "onecycle", "act": "leaky"}}


def spec_of(arch: str):
    return PILOTNET_SPEC if arch == "pilotnet" else SMALL_SPEC


def train_pilot(data: list[str | Path], out: str | Path, arch: str = "small", epochs: int = 15,
                batch_size: int | None = None, lr: float | None = None, width: int = 16,
                val_fraction: float = VAL_FRACTION, patience: int = 5, seed: int = 0, resume: bool = False,
                trainer_args: dict | None = None, workers: int = 0, quiet: bool = False, threads: int = 0,
                deterministic: bool = True, augment: AugmentParams | None = AugmentParams(),
                speed_weight: float = 0.1, balance: float = 0.0, schedule: str | None = None) -> dict:
    """Train; writes checkpoints/, logs/, tensorboard/, samples/epoch_<k>.png (val steering over
    time), config.json and report.json. lr, batch_size and the learning-rate schedule default per
    arch (DEFAULTS); balance: the power of the steering-balanced sampler
    (pilot_data.steering_weights; 0 = uniform)."""
    import lightning as L
    if arch not in DEFAULTS:
        raise ValueError(f"arch {arch!r}: one of {', '.join(DEFAULTS)}")
    lr = DEFAULTS[arch]["lr"] if lr is None else lr
    batch_size = DEFAULTS[arch]["batch_size"] if batch_size is None else batch_size
    schedule = DEFAULTS[arch]["schedule"] if schedule is None else schedule
    act = DEFAULTS[arch].get("act", "elu")  # small's activation (pilotnet has ELU, as published)
    out = Path(out)
    if threads > 0:
        torch.set_num_threads(threads)
    ckpt_path = resume_path(out, resume)
    L.seed_everything(seed, workers=True)
    spec = spec_of(arch)
    dm = PilotDataModule(data, spec, batch_size, val_fraction, augment, workers, seed, balance)
    dm.setup()
    task = PilotTask(arch=arch, lr=lr, speed_weight=speed_weight, input_size=(spec.width, spec.height), width=width,
                     schedule=schedule, act=act)
    task.samples_dir = out / "samples"
    info = RunInfo(data, {"arch": arch})
    save_run_config(out, {"task": "pilot", "arch": arch, "data": info.data, "data_hash": info.data_hash,
                          "epochs": epochs, "batch_size": batch_size, "lr": lr, "schedule": schedule, "width": width,
                          "act": act,
                          "speed_weight": speed_weight, "balance": balance, "val_fraction": val_fraction, "seed": seed,
                          "deterministic": deterministic, "input": [spec.width, spec.height],
                          "augment": None if augment is None else augment.__dict__,
                          "parameters": count_parameters(task.net), "train_frames": len(dm.train_items),
                          "val_frames": len(dm.val_items), "threads": threads, "trainer": trainer_args or {}})
    trainer, ckpt = build_trainer(out, epochs, "val/mae", "min", patience, trainer_args, [info], quiet=quiet,
                                  deterministic=deterministic)
    best, seconds = fit_best(trainer, ckpt, task, dm, out, ckpt_path)
    report = evaluate_checkpoint(best, PilotDataset(dm.val_items, dm.val_frames, spec))
    report.update({"arch": arch, "best_checkpoint": best, "train_seconds": round(seconds, 1),
                   "parameters": count_parameters(task.net), "train_frames": len(dm.train_items)})
    atomic_write_text(out / "report.json", json.dumps(report, indent=1))  # export puts it in the metadata
    return report


def evaluate_checkpoint(ckpt: str, ds: PilotDataset) -> dict:
    """Steering MAE / RMSE of a checkpoint on a dataset (no augmentation), overall and per desire."""
    task = PilotTask.load_from_checkpoint(ckpt, map_location="cpu").eval()
    preds, truth, desires = [], [], []
    with torch.no_grad():
        for i in range(0, len(ds), 256):
            batch = [ds[j] for j in range(i, min(len(ds), i + 256))]
            x = torch.stack([b[0] for b in batch])
            d = torch.stack([b[2] for b in batch])
            preds.append(pick_steering(task(x), d).numpy())
            truth.append(np.array([float(b[1]) for b in batch]))
            desires.append(d.numpy())
    p, t, d = np.concatenate(preds), np.concatenate(truth), np.concatenate(desires)
    err = p - t
    report = {"val_frames": int(len(t)), "val_steering_mae": round(float(np.abs(err).mean()), 5),
              "val_steering_rmse": round(float(np.sqrt((err ** 2).mean())), 5)}
    for k, name in enumerate(DESIRES):
        sel = d == k
        if sel.any() and name != "straight":
            report[f"val_steering_mae_{name}"] = round(float(np.abs(err[sel]).mean()), 5)
            report[f"val_frames_{name}"] = int(sel.sum())
    return report
