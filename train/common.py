"""Trainer set-up shared by every training task: loggers, checkpoints, early stopping, resume."""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import lightning as L
from lightning.pytorch.callbacks import EarlyStopping, ModelCheckpoint
from lightning.pytorch.loggers import CSVLogger, TensorBoardLogger

from signlane.fileio import atomic_write_text


@dataclass(frozen=True)
class ScaleOut:
    """Lightning's scale-out flags, passed straight through."""

    accelerator: str = "auto"
    devices: str = "auto"
    num_nodes: int = 1
    strategy: str = "auto"


def build_trainer(out: Path, epochs: int, monitor: str, mode: str, patience: int, scale: ScaleOut,
                  extra_callbacks: list | None = None, quiet: bool = False) -> tuple[L.Trainer, ModelCheckpoint]:
    """A Trainer writing CSV + TensorBoard logs and checkpoints (best by `monitor`, and last) to out."""
    ckpt = ModelCheckpoint(dirpath=out / "checkpoints", filename="best", monitor=monitor, mode=mode,
                           save_last=True, save_top_k=1)
    callbacks = [ckpt, EarlyStopping(monitor=monitor, mode=mode, patience=patience)] + (extra_callbacks or [])
    devices = int(scale.devices) if str(scale.devices).isdigit() else scale.devices
    trainer = L.Trainer(max_epochs=epochs, default_root_dir=out, callbacks=callbacks,
                        logger=[CSVLogger(out, name="logs"), TensorBoardLogger(out, name="tensorboard")],
                        accelerator=scale.accelerator, devices=devices, num_nodes=scale.num_nodes,
                        strategy=scale.strategy, enable_progress_bar=not quiet, enable_model_summary=not quiet,
                        log_every_n_steps=10, deterministic=False)
    return trainer, ckpt


def resume_path(out: Path, resume: bool) -> str | None:
    """The last checkpoint to resume from, when asked and one exists."""
    last = out / "checkpoints" / "last.ckpt"
    if resume and last.exists():
        return str(last)
    if resume:
        raise ValueError(f"--resume: no checkpoint at {last}")
    if last.exists():
        raise ValueError(f"{out} already holds a training run; pass --resume to continue it or choose another --out")
    return None


def save_run_config(out: Path, config: dict) -> None:
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(out / "config.json", json.dumps(config, indent=1, default=str))
