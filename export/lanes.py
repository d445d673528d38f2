"""`signlane export lanes CKPT --out lanes.onnx`: the segmentation net as ONNX with its contract,
checked (onnx.checker) and compared with torch (onnxruntime parity) or it raises."""
from __future__ import annotations

import json
from pathlib import Path

from signlane_export.onnx_export import data_hash, export_onnx, run_data_roots
from signlane.lanes.seg_model import CLASSES, DEFAULT_SPEC, TASK
from signlane.onnx_model import make_metadata


def export_lanes(ckpt: str | Path, out: str | Path, metrics: dict | None = None, tol: float = 1e-4) -> dict:
    """Export a lanes checkpoint; returns a report (parity, size, parameters). Without `metrics`
    the run's report.json val scores go into the metadata."""
    from signlane_train.lane_net import count_parameters
    from signlane_train.lane_task import LaneTask
    ckpt, out = Path(ckpt), Path(out)
    if not ckpt.is_file():
        raise ValueError(f"{ckpt}: checkpoint not found")
    try:
        task = LaneTask.load_from_checkpoint(str(ckpt), map_location="cpu").eval()
    except (KeyError, RuntimeError, TypeError) as e:
        raise ValueError(f"{ckpt}: not a lanes checkpoint ({type(e).__name__}: {str(e)[:120]})") from None
    spec = DEFAULT_SPEC
    run, roots = run_data_roots(ckpt)
    if metrics is None and (run / "report.json").exists():  # the run's val scores travel with the model
        report = json.loads((run / "report.json").read_text())
        metrics = {k: v for k, v in report.items() if k.startswith("val_")}
    meta = make_metadata(TASK, list(CLASSES), spec, data_hash(roots), metrics or {},
                         {"arch": f"LaneSegNet width {task.hparams.width}", "checkpoint": ckpt.name,
                          "output": json.dumps({"size": "input", "classes": list(CLASSES), "kind": "logits"})})
    report = export_onnx(task.net, (1, 3, spec.height, spec.width), out, meta, tol=tol)
    report["parameters"] = count_parameters(task.net)
    return report
