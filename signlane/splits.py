"""The train/validation split every dataset and training run shares: a file lands on the
validation side when the hash of its key (`<class>/<file>` for sign crops, the sample id for
lane frames) falls in the first `val_fraction` of the range. Stable across machines and runs,
and independent of what else is in the folder, so a dataset's train.txt / val.txt (written by
`signlane gen signs`) are exactly the split `signlane train` uses."""
from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Iterable

from signlane.fileio import atomic_write_text

VAL_FRACTION = 0.1


def split_of(key: str, val_fraction: float = VAL_FRACTION) -> str:
    """'train' or 'val' for a file's key."""
    h = int(hashlib.sha1(key.encode()).hexdigest()[:8], 16)
    return "val" if (h % 10000) / 10000.0 < val_fraction else "train"


def write_split_files(root: str | Path, keys: Iterable[str], val_fraction: float = VAL_FRACTION) -> dict[str, int]:
    """root/train.txt and root/val.txt: the keys (paths relative to root) on each side, sorted,
    one per line; returns the count per side."""
    root = Path(root)
    sides: dict[str, list[str]] = {"train": [], "val": []}
    for key in sorted(keys):
        sides[split_of(key, val_fraction)].append(key)
    for side, ks in sides.items():
        atomic_write_text(root / f"{side}.txt", "".join(k + "\n" for k in ks))
    return {side: len(ks) for side, ks in sides.items()}
