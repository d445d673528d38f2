"""`signlane export signs CKPT --out model.onnx [--int8]`: the classifier as ONNX with its contract."""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from signlane_export.onnx_export import export_onnx, load_task, present_data, quantize_int8, training_info
from signlane.onnx_model import make_metadata
from signlane.signs.classifier import DEFAULT_SPEC, TASK, SignClassifier, preprocess_crops
from signlane.world.art import SIGN_CLASSES


def export_signs(ckpt: str | Path, out: str | Path, int8: bool = False, metrics: dict | None = None) -> dict:
    """Export a sign checkpoint; returns a report (parity, sizes, the metadata's metrics and, while
    the training data still exists, the ONNX file's val accuracy, fp32 and int8). The metadata's
    data hash and metrics come from the checkpoint itself (`metrics` adds to them)."""
    from signlane_train.sign_task import SignTask
    ckpt, out = Path(ckpt), Path(out)
    if not ckpt.is_file():
        raise ValueError(f"{ckpt}: checkpoint not found")
    info = training_info(ckpt)  # first: a file that is no checkpoint gets its one line here
    task = load_task(ckpt, SignTask, "sign")
    size = int(task.hparams.size)
    spec = replace(DEFAULT_SPEC, width=size, height=size)
    metrics = {**info.get("metrics", {}), **(metrics or {})}
    roots = present_data(info)
    if int8 and roots is None:  # fail before writing anything
        raise ValueError(f"--int8 calibrates on the training data, which is gone: {', '.join(info.get('data') or ['?'])}")
    meta = make_metadata(TASK, list(SIGN_CLASSES), spec, info["data_hash"], metrics,
                         {"arch": "SignNet", "checkpoint": ckpt.name})
    report = export_onnx(task.net, (1, 3, size, size), out, meta)
    report.update({"data_hash": info["data_hash"], "metrics": metrics})
    val = _val_crops(roots, spec) if roots else None
    if val is not None:
        report["val_accuracy"] = _accuracy(out, *val)
    if int8:
        if val is None:
            raise ValueError(f"--int8: no val crops to calibrate on in {', '.join(roots)}")
        q = out.with_name(out.stem + "_int8.onnx")
        calib = [preprocess_crops(val[0][i:i + 64], spec) for i in range(0, min(len(val[0]), 1024), 64)]
        quantize_int8(out, q, calib)
        report["int8"] = {"path": str(q), "bytes": q.stat().st_size, "val_accuracy": _accuracy(q, *val)}
        report["int8"]["accuracy_drop"] = report["val_accuracy"] - report["int8"]["val_accuracy"]
    return report


def _val_crops(roots: list[str], spec) -> tuple[list[np.ndarray], np.ndarray] | None:
    import cv2
    from signlane_train.sign_data import list_crops, on_side
    items = on_side(list_crops([Path(r) for r in roots]), "val")
    if not items:
        return None
    return [cv2.imread(str(p)) for p, _ in items], np.array([label for _, label in items])


def _accuracy(model_path: Path, crops: list[np.ndarray], labels: np.ndarray) -> float:
    clf = SignClassifier(model_path, threads=2, batch=256)
    pred = clf.probabilities(crops).argmax(axis=1)
    return float((pred == labels).mean())
