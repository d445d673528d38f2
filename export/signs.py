"""`signlane export signs CKPT --out model.onnx [--int8]`: the classifier as ONNX with its contract;
`signlane quantize signs MODEL.onnx --data DIR --out int8.onnx`: an exported one as int8."""
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
        fp32 = _predict(out, val[0])
        report["val_accuracy"] = float((fp32 == val[1]).mean())
    if int8:
        if val is None:
            raise ValueError(f"--int8: no val crops to calibrate on in {', '.join(roots)}")
        report["int8"] = _int8(out, out.with_name(out.stem + "_int8.onnx"), val, fp32, spec, roots)
    return report


def quantize_signs(model: str | Path, data: list[str | Path], out: str | Path) -> dict:
    """An exported fp32 sign classifier as int8 (QDQ, per-channel weights), calibrated on the val
    crops of `data` (a `signlane gen signs` set: its training data, or one made the same way).
    The int8 file runs the classifier's convolutions about three times faster on one thread;
    the report gives both files' accuracy on those crops and how often their labels agree, so a
    quantization that costs accuracy is seen before it is shipped."""
    model, out = Path(model), Path(out)
    spec = SignClassifier(model).model.input  # the contract first: one line for a file that is no classifier
    if _is_quantized(model):
        raise ValueError(f"{model}: already quantized (it holds QuantizeLinear nodes); quantize the fp32 export")
    roots = [str(d) for d in data]
    val = _val_crops(roots, spec)
    if val is None:
        raise ValueError(f"{', '.join(roots)}: no val crops to calibrate on")
    fp32 = _predict(model, val[0])
    report = {"model": str(model), "val_crops": len(val[1]), "val_accuracy": float((fp32 == val[1]).mean())}
    report["int8"] = _int8(model, out, val, fp32, spec, roots)
    return report


CALIBRATION_CROPS = 1024  # val crops the int8 ranges are calibrated on (all of them below that)


def _int8(src: Path, dst: Path, val: tuple[list[np.ndarray], np.ndarray], fp32: np.ndarray, spec,
          roots: list[str]) -> dict:
    """Quantize src to dst on val's first crops; dst's accuracy on all of val, its drop from src's
    and how often its label is src's (`fp32`: src's labels of val)."""
    crops, labels = val
    n = min(len(crops), CALIBRATION_CROPS)
    calib = [preprocess_crops(crops[i:min(i + 64, n)], spec) for i in range(0, n, 64)]
    note = f"int8 (QDQ, per-channel weights), calibrated on {n} val crops of {', '.join(roots)}; from {src.name}"
    quantize_int8(src, dst, calib, {"signlane.quantized": note})
    int8 = _predict(dst, crops)
    accuracy = float((int8 == labels).mean())
    return {"path": str(dst), "bytes": dst.stat().st_size, "calibration_crops": n, "val_accuracy": accuracy,
            "accuracy_drop": float((fp32 == labels).mean()) - accuracy, "agreement": float((int8 == fp32).mean())}


def _is_quantized(path: Path) -> bool:
    import onnx
    return any(n.op_type in ("QuantizeLinear", "QLinearConv") for n in onnx.load(str(path)).graph.node)


def _val_crops(roots: list[str], spec) -> tuple[list[np.ndarray], np.ndarray] | None:
    import cv2
    from signlane_train.sign_data import list_crops, on_side
    items = on_side(list_crops([Path(r) for r in roots]), "val")
    if not items:
        return None
    return [cv2.imread(str(p)) for p, _ in items], np.array([label for _, label in items])


def _predict(model_path: Path, crops: list[np.ndarray]) -> np.ndarray:
    """The model's label (class index) of each crop."""
    return SignClassifier(model_path, threads=2, batch=256).probabilities(crops).argmax(axis=1)
