"""`signlane autolabel signs`: proposals + the current classifier on a user's own images and
videos, written as a reviewable ImageFolder (move a wrong crop to its right folder, then train on
the folder) with one contact sheet per class."""
from __future__ import annotations

import json
import logging
import sys
from collections import Counter
from pathlib import Path

import cv2
from tqdm import tqdm

from signlane.draw import contact_sheet, write_image
from signlane.fileio import atomic_write_text
from signlane.media import MediaError, expand, iter_frames
from signlane.signs.classifier import DEFAULT_MODEL, SignClassifier, crop
from signlane.signs.proposals import propose
from signlane.world.art import SIGN_CLASSES

log = logging.getLogger(__name__)


def autolabel_signs(paths: list[str], out: str | Path, model: str | Path | None = None, every: int = 10,
                    size: int = 48, progress: bool = True) -> dict:
    """Crops of every proposal, foldered by the classifier's label; returns counts per class and
    the inputs that failed. Without a classifier model every crop goes to 'unknown'."""
    out = Path(out)
    path = Path(model) if model else DEFAULT_MODEL
    clf = SignClassifier(path) if (model or DEFAULT_MODEL.exists()) else None
    if clf is None:
        log.warning("no classifier model (%s): every proposal is filed as 'unknown'", path)
    sources, failed = expand(paths)
    for e in failed:
        print(f"signlane autolabel: {e}", file=sys.stderr)
    counts: Counter = Counter()
    for src in tqdm(sources, desc="autolabel", unit="input", disable=not progress or len(sources) < 2):
        try:
            for index, frame in iter_frames(src, every):
                crops = [crop(frame, p.box) for p in propose(frame)]
                labels = [r[0] for r in clf.classify(crops)] if clf and crops else ["unknown"] * len(crops)
                for k, (c, label) in enumerate(zip(crops, labels)):
                    name = f"{src.path.stem}_{index:06d}_{k:02d}.png"
                    write_image(out / label / name, cv2.resize(c, (size, size), interpolation=cv2.INTER_AREA))
                    counts[label] += 1
        except MediaError as e:
            print(f"signlane autolabel: {e}", file=sys.stderr)
            failed.append(str(e))
    for label in SIGN_CLASSES:
        files = sorted((out / label).glob("*.png")) if (out / label).is_dir() else []
        if files:
            sheet = contact_sheet([cv2.imread(str(f)) for f in files[:96]], cols=12, tile=(64, 64))
            write_image(out / f"sheet_{label}.png", sheet)
    report = {"counts": dict(counts), "model": str(path) if clf else None, "failed": failed}
    atomic_write_text(out / "autolabel.json", json.dumps(report, indent=1))
    return report
