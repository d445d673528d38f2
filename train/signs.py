"""`signlane train signs`: train the sign classifier on ImageFolder crops; report what it gets wrong."""
from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import torch

from signlane.sign_report import write_sign_report
from signlane.splits import VAL_FRACTION
from signlane.world.art import SIGN_CLASSES
from signlane_train.common import build_trainer, fit_best, resume_path, save_run_config
from signlane_train.run_info import RunInfo
from signlane_train.sign_data import CropDataset, SignDataModule
from signlane_train.sign_task import SignTask

log = logging.getLogger(__name__)


def train_signs(data: list[str | Path], out: str | Path, epochs: int = 20, batch_size: int = 128, lr: float = 3e-3,
                size: int = 32, val_fraction: float = VAL_FRACTION, patience: int = 6, seed: int = 0, resume: bool = False,
                trainer_args: dict | None = None, workers: int = 0, quiet: bool = False, width: int = 16,
                class_weights: str = "sqrt", threads: int = 0, augment: float = 1.0,
                deterministic: bool = True) -> dict:
    """Train; writes checkpoints/, logs/, tensorboard/, config.json, confusion.png, errors_<class>.png.
    class_weights 'sqrt' weighs the loss by square-root inverse class frequency; 'none' weighs every
    crop alike, so the many 'unknown' crops pull harder against taking a non-sign for a sign.
    threads > 0 caps torch's CPU threads (see train_lanes); augment (0..1) scales how often each
    training augmentation is applied; deterministic (the default) asks torch for deterministic
    algorithms, so the same seed repeats a run exactly (on GPUs too). Every checkpoint carries the
    data's content hash and its validation scores (signlane_train.run_info), for export."""
    if class_weights not in ("sqrt", "none"):
        raise ValueError(f"class_weights must be 'sqrt' or 'none', not {class_weights!r}")
    if not 0.0 <= augment <= 1.0:
        raise ValueError(f"augment must be within 0..1, not {augment}")
    import lightning as L
    from dataclasses import replace
    from signlane.signs.classifier import DEFAULT_SPEC
    out = Path(out)
    ckpt_path = resume_path(out, resume)
    L.seed_everything(seed, workers=True)
    if threads > 0:
        torch.set_num_threads(threads)
    spec = replace(DEFAULT_SPEC, width=size, height=size)
    dm = SignDataModule(data, batch_size, val_fraction, spec, workers, augment, seed)
    dm.setup()
    weights = dm.class_weights().tolist() if class_weights == "sqrt" else None
    task = SignTask(size=size, lr=lr, epochs=epochs, class_weights=weights, width=width)
    info = RunInfo(data)
    save_run_config(out, {"task": "signs", "data": info.data, "data_hash": info.data_hash, "epochs": epochs,
                          "batch_size": batch_size, "lr": lr, "size": size, "width": width, "class_weights": class_weights,
                          "augment": augment,
                          "val_fraction": val_fraction, "workers": workers, "threads": threads,
                          "seed": seed, "deterministic": deterministic, "train_crops": len(dm.train_items),
                          "val_crops": len(dm.val_items),
                          "trainer": trainer_args or {}})
    trainer, ckpt = build_trainer(out, epochs, "val/acc", "max", patience, trainer_args, [info], quiet=quiet,
                                  deterministic=deterministic)
    best, seconds = fit_best(trainer, ckpt, task, dm, out, ckpt_path)
    report = evaluate_checkpoint(best, dm.val_items, spec, out)
    report.update({"best_checkpoint": best, "train_seconds": round(seconds, 1)})
    return report


def evaluate_checkpoint(ckpt: str, items, spec, out: Path | None = None) -> dict:
    """Accuracy, per-class recall and non-sign acceptance of a checkpoint on (path, label) items;
    writes confusion.png and errors_<class>.png to out when given."""
    task = SignTask.load_from_checkpoint(ckpt, map_location="cpu").eval()
    ds = CropDataset(items, spec)
    probs, labels = [], []
    with torch.no_grad():
        for i in range(0, len(ds), 512):
            batch = [ds[j] for j in range(i, min(len(ds), i + 512))]
            x = torch.stack([b[0] for b in batch])
            probs.append(torch.softmax(task(x), 1).numpy())
            labels += [b[1] for b in batch]
    prob, y = np.concatenate(probs), np.array(labels)
    pred = prob.argmax(1)
    report = classification_report(pred, y)
    if out is not None:
        write_sign_report(out, [it[0] for it in items], y, pred, prob.max(1), SIGN_CLASSES, "validation")
    return report


def classification_report(pred: np.ndarray, y: np.ndarray) -> dict:
    n = len(SIGN_CLASSES)
    conf = np.zeros((n, n), np.int64)
    np.add.at(conf, (y, pred), 1)
    recall = {c: float(conf[i, i] / max(conf[i].sum(), 1)) for i, c in enumerate(SIGN_CLASSES)}
    unknown = SIGN_CLASSES.index("unknown")
    non_sign_accepted = float(1.0 - recall["unknown"]) if conf[unknown].sum() else 0.0
    return {"accuracy": float((pred == y).mean()), "recall": recall, "non_sign_accepted": non_sign_accepted,
            "n": int(len(y)), "confusion": conf.tolist()}


