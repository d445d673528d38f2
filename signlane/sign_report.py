"""Pictures of a sign classifier's results on a crop set, the same for training's validation
set and `signlane eval signs` on any test set: confusion.png (every count, full class names)
and errors_<class>.png, the crops of a class it got wrong, each captioned with its file name,
what it was taken for and that score; errors_<class>.txt lists the same files in tile order,
with their full paths, so every tile traces back to its file."""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

import cv2
import numpy as np

from signlane.draw import contact_sheet, write_image
from signlane.fileio import atomic_write_text


def write_sign_report(out: str | Path, files: Sequence[str | Path], y: np.ndarray, pred: np.ndarray,
                      score: np.ndarray, classes: Sequence[str], set_name: str, per_class: int = 48) -> None:
    from signlane.plots import confusion_matrix
    out = Path(out)
    y, pred = np.asarray(y), np.asarray(pred)
    conf = np.zeros((len(classes), len(classes)), np.int64)
    np.add.at(conf, (y, pred), 1)
    title = f"{set_name}: {len(y)} crops, accuracy {100 * float((pred == y).mean()):.2f}%"
    write_image(out / "confusion.png", confusion_matrix(conf, classes, title))
    for k, name in enumerate(classes):
        wrong = np.flatnonzero((y == k) & (pred != k))[:per_class]
        sheet, listing = out / f"errors_{name}.png", out / f"errors_{name}.txt"
        if len(wrong) == 0:  # none wrong now: an old sheet must not stay behind
            sheet.unlink(missing_ok=True)
            listing.unlink(missing_ok=True)
            continue
        crops = [cv2.imread(str(files[i])) for i in wrong]
        crops = [c if c is not None else np.zeros((8, 8, 3), np.uint8) for c in crops]
        captions = [f"{Path(files[i]).stem[-12:]}\n{classes[pred[i]]} {score[i]:.2f}" for i in wrong]
        write_image(sheet, contact_sheet(crops, cols=8, tile=(112, 112), captions=captions, scale=0.38, band=True))
        atomic_write_text(listing, f"# true class {name}: tile, file, taken for, score\n" + "".join(
            f"{n}\t{files[i]}\t{classes[pred[i]]}\t{score[i]:.4f}\n" for n, i in enumerate(wrong)))
