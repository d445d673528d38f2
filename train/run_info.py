"""What export needs, carried inside every checkpoint: the training data's content hash, the data
folders (absolute, for optional checks while they still exist) and the validation scores of the
epoch saved. A checkpoint then exports on its own, from any working folder, after the data and
the run folder are gone."""
from __future__ import annotations

import math
from pathlib import Path

from lightning.pytorch.callbacks import Callback

from signlane_data.content_hash import content_hash

KEY = "signlane"  # the checkpoint dict's entry


class RunInfo(Callback):
    def __init__(self, data: list[str | Path], extra: dict | None = None):
        self.data = [str(Path(d).resolve()) for d in data]
        self.data_hash = content_hash(self.data)
        self.extra = dict(extra or {})

    def on_save_checkpoint(self, trainer, pl_module, checkpoint: dict) -> None:
        checkpoint[KEY] = {"data": self.data, "data_hash": self.data_hash, "epoch": int(trainer.current_epoch),
                           "metrics": val_metrics(trainer.callback_metrics), **self.extra}


def val_metrics(logged: dict) -> dict[str, float]:
    """Lightning's logged `val/...` values as plain `val_...` floats (JSON-ready, finite only)."""
    out = {}
    for k, v in logged.items():
        if not k.startswith("val/"):
            continue
        f = float(v)
        if math.isfinite(f):
            out["val_" + k[4:]] = round(f, 6)
    return out
