"""How a lane dataset's label masks (`masks/<id>.png`, `drivable/<id>.png`) encode their classes:
written and read here only, by the generators, training, `signlane eval masks` and the previews.

Datasets made now follow the segmentation convention of torchvision, mmseg and
segmentation_models: a uint8 PNG of class ids at the frame's size, 0 = background, 1 = the class
(lane marking in `masks/`, road surface in `drivable/`), 255 = ignore (the pixel has no valid
label: no loss and no metric counts it). The dataset's `manifest.json` says so with
`"mask_encoding": "ids-0-1-255ignore"`. Datasets made before (no such key), and folders made by
hand without a manifest, are binary: 0 background, any other value (255) the class, nothing
ignored; they read as the same ids. A folder made by hand in the ids encoding says so with a
`manifest.json` of its own holding the key (a mask of 1s and 255s in a folder that does not is
refused, not read as paint).
"""
from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np

MANIFEST_KEY = "mask_encoding"
IDS = "ids-0-1-255ignore"
BINARY = "binary-0-255"  # before the key existed: what a dataset without it holds
ENCODINGS = (IDS, BINARY)
IGNORE = 255


def encode(on: np.ndarray, ignore: np.ndarray | None = None) -> np.ndarray:
    """bool (H, W) pixels of the class, and optionally bool (H, W) pixels without a label ->
    uint8 (H, W) ids: 1 on the class, 255 where ignored (a pixel of the class keeps its 1), else 0."""
    ids = on.astype(np.uint8)
    if ignore is not None:
        ids[ignore & ~on.astype(bool)] = IGNORE
    return ids


def dataset_encoding(root: str | Path) -> str:
    """The mask encoding of the lane dataset folder `root`: its manifest's `mask_encoding`, or
    BINARY when the manifest has no such key or the folder has no manifest. Raises ValueError
    for an unreadable manifest or an encoding this version does not know."""
    path = Path(root) / "manifest.json"
    if not path.is_file():
        return BINARY
    try:
        manifest = json.loads(path.read_text())
    except (OSError, ValueError) as e:
        raise ValueError(f"{path}: unreadable manifest ({e})") from None
    encoding = manifest.get(MANIFEST_KEY, BINARY) if isinstance(manifest, dict) else BINARY
    if encoding not in ENCODINGS:
        raise ValueError(f"{path}: {MANIFEST_KEY} {encoding!r} is not one this version reads "
                         f"({', '.join(ENCODINGS)})")
    return encoding


def decode(raw: np.ndarray, encoding: str, name: str = "mask") -> np.ndarray:
    """uint8 (H, W) mask as stored in a dataset of `encoding` -> uint8 (H, W) ids 0/1/255 (see
    the module docstring). Raises ValueError naming `name` for a value the encoding does not
    have (an ids mask holds only 0, 1 and 255), and for a binary one that holds both 1 and 255:
    that is an ids mask whose folder does not say so, and reading its 255s as paint would train
    on them."""
    if encoding == BINARY:
        on = raw > 0
        if (raw == IGNORE).any() and (raw == 1).any():
            raise ValueError(f"{name}: holds 1s and 255s like a {IDS} mask, but its folder's manifest.json "
                             f"names no {MANIFEST_KEY} (binary 0/255 assumed); add "
                             f'"{MANIFEST_KEY}": "{IDS}" to it')
        return on.astype(np.uint8)
    if encoding != IDS:
        raise ValueError(f"{name}: unknown mask encoding {encoding!r} ({', '.join(ENCODINGS)})")
    bad = (raw > 1) & (raw != IGNORE)
    if bad.any():
        raise ValueError(f"{name}: value {int(raw[bad][0])} in a {IDS} mask (only 0, 1 and {IGNORE})")
    return raw


def read_mask(path: str | Path, encoding: str) -> np.ndarray:
    """The mask file `path` of a dataset of `encoding` as uint8 (H, W) ids 0/1/255; ValueError
    when it cannot be read or holds a value the encoding does not have."""
    raw = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    if raw is None:
        raise ValueError(f"{path}: unreadable mask")
    return decode(raw, encoding, str(path))
