"""`signlane train signs`: train the sign classifier on ImageFolder crops; report what it gets wrong."""
from __future__ import annotations

import logging
import time
from pathlib import Path

import cv2
import numpy as np
import torch

from signlane.draw import contact_sheet, write_image
from signlane.world.art import SIGN_CLASSES
from signlane_train.common import ScaleOut, build_trainer, resume_path, save_run_config
from signlane_train.run_info import RunInfo
from signlane_train.sign_data import CropDataset, SignDataModule
from signlane_train.sign_task import SignTask

log = logging.getLogger(__name__)


def train_signs(data: list[str | Path], out: str | Path, epochs: int = 20, batch_size: int = 128, lr: float = 3e-3,
                size: int = 32, val_fraction: float = 0.1, patience: int = 6, seed: int = 0, resume: bool = False,
                scale: ScaleOut = ScaleOut(), workers: int = 0, quiet: bool = False, width: int = 16,
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
                          "scale_out": scale.__dict__})
    trainer, ckpt = build_trainer(out, epochs, "val/acc", "max", patience, scale, [info], quiet=quiet,
                                  deterministic=deterministic)
    t0 = time.perf_counter()
    trainer.fit(task, datamodule=dm, ckpt_path=ckpt_path)
    seconds = time.perf_counter() - t0
    best = ckpt.best_model_path or str(out / "checkpoints" / "last.ckpt")
    report = evaluate_checkpoint(best, dm.val_items, spec, out)
    report.update({"best_checkpoint": best, "train_seconds": round(seconds, 1)})
    return report


def evaluate_checkpoint(ckpt: str, items, spec, out: Path | None = None) -> dict:
    """Accuracy, per-class recall and non-sign acceptance of a checkpoint on (path, label) items;
    writes confusion.png and errors_<class>.png to out when given."""
    task = SignTask.load_from_checkpoint(ckpt, map_location="cpu").eval()
    ds = CropDataset(items, spec)
    preds, labels = [], []
    with torch.no_grad():
        for i in range(0, len(ds), 512):
            batch = [ds[j] for j in range(i, min(len(ds), i + 512))]
            x = torch.stack([b[0] for b in batch])
            preds.append(task(x).argmax(1).numpy())
            labels += [b[1] for b in batch]
    pred, y = np.concatenate(preds), np.array(labels)
    report = classification_report(pred, y)
    if out is not None:
        write_image(out / "confusion.png", confusion_image(report["confusion"]))
        _write_errors(out, items, pred, y)
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


def confusion_image(conf: list[list[int]], cell: int = 56) -> np.ndarray:
    """Row-normalised confusion matrix (rows = truth) as a picture with counts."""
    m = np.array(conf, float)
    norm = m / np.maximum(m.sum(axis=1, keepdims=True), 1)
    n = len(SIGN_CLASSES)
    pad = 90
    img = np.full((pad + n * cell + 10, pad + n * cell + 10, 3), 255, np.uint8)
    for i in range(n):
        for j in range(n):
            v = norm[i, j]
            col = (int(255 * (1 - v)), int(255 * (1 - 0.6 * v)), 255) if i != j else (int(255 * (1 - v)), 255, int(255 * (1 - v)))
            x, yy = pad + j * cell, pad + i * cell
            cv2.rectangle(img, (x, yy), (x + cell - 2, yy + cell - 2), col, -1)
            cv2.putText(img, str(int(m[i, j])), (x + 4, yy + cell // 2 + 4), cv2.FONT_HERSHEY_SIMPLEX, 0.38, (0, 0, 0), 1)
        cv2.putText(img, SIGN_CLASSES[i][:9], (2, pad + i * cell + cell // 2 + 4), cv2.FONT_HERSHEY_SIMPLEX, 0.38, (0, 0, 0), 1)
        cv2.putText(img, SIGN_CLASSES[i][:7], (pad + i * cell + 2, pad - 8), cv2.FONT_HERSHEY_SIMPLEX, 0.36, (0, 0, 0), 1)
    cv2.putText(img, "truth (rows) vs predicted (columns)", (4, 20), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 1)
    return img


def _write_errors(out: Path, items, pred: np.ndarray, y: np.ndarray, per_class: int = 32) -> None:
    """errors_<class>.png: crops of that class the model got wrong, captioned with the prediction."""
    for k, name in enumerate(SIGN_CLASSES):
        wrong = np.nonzero((y == k) & (pred != k))[0][:per_class]
        path = out / f"errors_{name}.png"
        if len(wrong) == 0:
            path.unlink(missing_ok=True)
            continue
        crops = [cv2.imread(str(items[i][0])) for i in wrong]
        write_image(path, contact_sheet(crops, cols=8, tile=(64, 64), captions=[SIGN_CLASSES[pred[i]] for i in wrong]))
