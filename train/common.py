"""Trainer set-up shared by every training task: loggers, checkpoints, early stopping, resume."""
from __future__ import annotations

import json
import logging
import random
import time
import zipfile
from pathlib import Path

import lightning as L
import numpy as np
import torch
from lightning.pytorch.callbacks import EarlyStopping, ModelCheckpoint
from lightning.pytorch.loggers import CSVLogger, TensorBoardLogger

from signlane.commands.trainer_flags import RUN_OWNED  # the run's own: checkpoints, logs, epochs
from signlane.fileio import atomic_write_text

# lightning gives its logger a stderr handler of its own and still lets it propagate: with the
# command line's root handler every line of it came out twice. The root handler prints them.
if logging.getLogger().hasHandlers():
    for _h in list(logging.getLogger("lightning").handlers):
        logging.getLogger("lightning").removeHandler(_h)


def channels_last(net: torch.nn.Module) -> torch.nn.Module:
    """The net with channels-last weights; feed it `as_channels_last` batches. Its convolutions
    then train faster on the CPU (a fwd/bwd step on 2 threads: the lane net 0.49 -> 0.33 s a
    batch of 32, PilotNet 0.17 -> 0.13 s and our small pilot 0.030 -> 0.026 s a batch of 64,
    the sign net 10-25 %). A training detail only: the same numbers in another memory order, and
    the exported graph does not see it."""
    return net.to(memory_format=torch.channels_last)


def as_channels_last(x: torch.Tensor) -> torch.Tensor:
    return x.contiguous(memory_format=torch.channels_last)


def one_cycle(module: L.LightningModule, opt: torch.optim.Optimizer, max_lr: float, pct_start: float) -> dict:
    """configure_optimizers' answer for a one-cycle rate: warm up over pct_start of the run's steps,
    then anneal to near zero, stepped per batch. The rate ends low, so the last epochs settle
    instead of jumping between minima (the best checkpoint is less a matter of luck)."""
    total = max(10, int(module.trainer.estimated_stepping_batches))  # OneCycle needs a few steps per phase
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=max_lr, total_steps=total, pct_start=pct_start)
    return {"optimizer": opt, "lr_scheduler": {"scheduler": sched, "interval": "step"}}


def build_trainer(out: Path, epochs: int, monitor: str, mode: str, patience: int, trainer_args: dict | None = None,
                  extra_callbacks: list | None = None, quiet: bool = False,
                  deterministic: bool = True) -> tuple[L.Trainer, ModelCheckpoint]:
    """A Trainer writing CSV + TensorBoard logs and checkpoints to out: best.ckpt (by `monitor`)
    and last.ckpt after every epoch, so --resume continues from the last finished epoch.
    trainer_args: any other Lightning Trainer arguments (accelerator, devices, precision,
    gradient_clip_val, ...), passed straight through. deterministic: torch's deterministic
    algorithms wherever an op has one ("warn": an op without one, on some GPU, warns instead of
    stopping the run)."""
    trainer_args = dict(trainer_args or {})
    owned = sorted(set(trainer_args) & set(RUN_OWNED))
    if owned:
        raise ValueError(f"Trainer argument(s) {', '.join(owned)} are set by the run itself")
    ckpt = ModelCheckpoint(dirpath=out / "checkpoints", filename="best", monitor=monitor, mode=mode, save_top_k=1)
    # its own callback: ModelCheckpoint(save_last=True) writes last only when `monitor` improves
    last = ModelCheckpoint(dirpath=out / "checkpoints", filename="last", monitor=None, save_top_k=1,
                           every_n_epochs=1, enable_version_counter=False)
    callbacks = [ckpt, last, EarlyStopping(monitor=monitor, mode=mode, patience=patience)] + (extra_callbacks or [])
    args = {"enable_progress_bar": not quiet, "enable_model_summary": not quiet, "log_every_n_steps": 10,
            **trainer_args}
    trainer = L.Trainer(max_epochs=epochs, default_root_dir=out, callbacks=callbacks,
                        logger=[CSVLogger(out, name="logs"), TensorBoardLogger(out, name="tensorboard")],
                        deterministic="warn" if deterministic else False, **args)
    return trainer, ckpt


def fit_best(trainer: L.Trainer, ckpt: ModelCheckpoint, task, datamodule, out: Path,
             ckpt_path: str | None) -> tuple[str, float]:
    """Train (resuming from ckpt_path, if any); -> (the best checkpoint, or last.ckpt where
    none was judged best, and the training seconds)."""
    t0 = time.perf_counter()
    trainer.fit(task, datamodule=datamodule, ckpt_path=ckpt_path)
    return ckpt.best_model_path or str(out / "checkpoints" / "last.ckpt"), time.perf_counter() - t0


def seed_worker(worker_id: int) -> None:
    """DataLoader worker_init_fn: each worker's own seed (torch gives worker k the base seed + k,
    the base drawn from the seeded main process) for numpy, random and the dataset's
    albumentations pipeline, which keeps a generator of its own: without this every worker
    would start from one copy of it and draw the same augmentations as its siblings."""
    seed = torch.initial_seed() % 2**32
    np.random.seed(seed)
    random.seed(seed)
    augment = getattr(torch.utils.data.get_worker_info().dataset, "augment", None)
    if augment is not None:
        augment.set_random_seed(seed)


def resume_path(out: Path, resume: bool) -> str | None:
    """The last checkpoint to resume from, when asked and one exists."""
    last = out / "checkpoints" / "last.ckpt"
    if resume and last.exists():
        check_checkpoint(last)
        return str(last)
    if resume:
        raise ValueError(f"--resume: no checkpoint at {last}")
    if last.exists():
        raise ValueError(f"{out} already holds a training run; pass --resume to continue it or choose another --out")
    return None


def check_checkpoint(path: Path) -> None:
    """A checkpoint torch can open: a whole zip archive whose members pass their CRCs (a run
    killed while saving leaves a truncated file); ValueError in one line otherwise."""
    hint = "delete it to start the run again, or copy best.ckpt over it to continue from the best epoch"
    try:
        with zipfile.ZipFile(path) as z:
            bad = z.testzip()
    except (zipfile.BadZipFile, OSError, EOFError) as e:
        raise ValueError(f"--resume: {path} is damaged ({e}); {hint}") from None
    if bad is not None:
        raise ValueError(f"--resume: {path} is damaged ({bad} fails its CRC check); {hint}")


def save_run_config(out: Path, config: dict) -> None:
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(out / "config.json", json.dumps(config, indent=1, default=str))
