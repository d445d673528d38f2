"""`signlane eval pilot DRIVE_DIR --model FILE [--model FILE2]`: pilots scored offline against
the teacher on recorded drives (donkeycar's "pilot arena": models side by side on the same frames).

Each recorded frame goes through the runtime's own pre-processing, with the desire the planner
had then; the error is the model's steering minus the teacher's (the recording's label). Rows:
overall, per bin of the teacher's lane curvature (straight, bend, tight turn), per desire. With
`out`: steering.png (teacher and each model over time, the first drive) and
disagree_<model>.png (the frames where that model and the teacher differ most, captioned).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
from tqdm import tqdm

from signlane.pilot import PilotModel, read_outputs, read_pilot_frames

# |curvature| bins, 1/m: a straight road; a bend (radius 100 m down to 17 m); a turn (VIA's are 6 and 14 m)
CURVATURE_BINS = ((0.0, 0.01, "straight |k|<0.01"), (0.01, 0.06, "bend 0.01-0.06"), (0.06, 1e9, "turn |k|>=0.06"))
BATCH = 64


@dataclass
class Frames:
    """The frames of the drives, in order: paths, labels and what the planner had."""
    paths: list[Path] = field(default_factory=list)
    steering: list[float] = field(default_factory=list)
    desire: list[str] = field(default_factory=list)
    curvature: list[float] = field(default_factory=list)
    drive: list[str] = field(default_factory=list)


def read_frames(roots: list[str | Path]) -> Frames:
    """Every frame of every recording under the roots (ValueError naming a root with none)."""
    items = read_pilot_frames(roots)
    return Frames([f.image for f in items], [f.steering for f in items], [f.desire for f in items],
                  [f.curvature for f in items], [f.drive for f in items])


def predict(model: PilotModel, frames: Frames, desc: str = "") -> np.ndarray:
    """float32 (N,) steering of `model` on every frame, for the frame's desire."""
    out = np.empty(len(frames.paths), np.float32)
    for i in tqdm(range(0, len(frames.paths), BATCH), desc=desc or "pilot", unit="batch", leave=False):
        imgs = []
        for p in frames.paths[i:i + BATCH]:
            img = cv2.imread(str(p), cv2.IMREAD_COLOR)
            if img is None:
                raise ValueError(f"{p}: unreadable")
            imgs.append(img)
        rows = model.predict(imgs)
        for k, row in enumerate(rows):
            out[i + k] = read_outputs(row, model.classes, frames.desire[i + k]).steering
    return out


def scores(pred: np.ndarray, frames: Frames) -> dict[str, dict]:
    """{row name: {"frames", "mae", "rmse"}}: all frames, per curvature bin, per desire."""
    err = pred - np.asarray(frames.steering, np.float32)
    k = np.abs(np.asarray(frames.curvature))
    desire = np.asarray(frames.desire)
    sel = {"all": np.ones(len(err), bool)}
    sel.update({name: (k >= lo) & (k < hi) for lo, hi, name in CURVATURE_BINS})
    sel.update({f"desire {d}": desire == d for d in ("left", "straight", "right")})
    out = {}
    for name, m in sel.items():
        if m.any():
            e = err[m]
            out[name] = {"frames": int(m.sum()), "mae": float(np.abs(e).mean()), "rmse": float(np.sqrt((e ** 2).mean()))}
    return out


def disagreement_sheet(pred: np.ndarray, frames: Frames, name: str, n: int = 12) -> np.ndarray:
    """The n frames where `name` and the teacher differ most, captioned with both steerings."""
    from signlane.draw import contact_sheet
    err = np.abs(pred - np.asarray(frames.steering))
    worst = np.argsort(-err)[:n]
    tiles, captions = [], []
    for i in worst:
        img = cv2.imread(str(frames.paths[i]), cv2.IMREAD_COLOR)
        tiles.append(cv2.resize(img, (320, 240), interpolation=cv2.INTER_AREA))
        captions.append(f"{frames.drive[i]}/{frames.paths[i].stem} {frames.desire[i]}\n"
                        f"teacher {frames.steering[i]:+.2f}  {name} {pred[i]:+.2f}")
    return contact_sheet(tiles, cols=4, captions=captions)


def eval_pilot(roots: list[str | Path], models: list[str | Path], out: str | Path | None = None) -> dict:
    """Score each model on the recordings; returns {"frames", "models": {label: scores}} and
    writes the pictures to `out`. Model labels are the file stems (made unique)."""
    frames = read_frames(roots)
    preds: dict[str, np.ndarray] = {}
    for path in models:
        model = PilotModel(path)
        label, k = Path(path).stem, 2
        while label in preds:  # the same stem twice (run1/pilot.onnx, run2/pilot.onnx): pilot, pilot_2
            label, k = f"{Path(path).stem}_{k}", k + 1
        preds[label] = predict(model, frames, label)
    result = {"frames": len(frames.paths), "drives": len(set(frames.drive)),
              "models": {k: scores(p, frames) for k, p in preds.items()}}
    if out is not None:
        from signlane.draw import write_image
        from signlane.plots import steering_chart
        out = Path(out)
        first = np.flatnonzero(np.asarray(frames.drive) == frames.drive[0])
        write_image(out / "steering.png", steering_chart(np.asarray(frames.steering)[first],
                                                         {k: p[first] for k, p in preds.items()},
                                                         f"frame of drive {frames.drive[0]}"))
        for k, p in preds.items():
            write_image(out / f"disagree_{k}.png", disagreement_sheet(p, frames, k))
    return result


def format_table(result: dict) -> str:
    from signlane.tables import table
    names = list(result["models"])
    rows_order = list(next(iter(result["models"].values())))
    rows = []
    for r in rows_order:
        first = result["models"][names[0]][r]
        rows.append([r, first["frames"]] + [f"{result['models'][m][r]['mae']:.4f} / {result['models'][m][r]['rmse']:.4f}"
                                             if r in result["models"][m] else "n/a" for m in names])
    return table(["frames", "n"] + [f"{m} MAE / RMSE" for m in names], rows)
