"""`signlane export lanes CKPT --out lanes.onnx`: the segmentation net as ONNX with its contract,
checked (onnx.checker) and compared with torch (onnxruntime parity) or it raises."""
from __future__ import annotations

import json
from pathlib import Path

from signlane_export.onnx_export import export_onnx, load_task, run_metrics, training_info
from signlane.lanes.seg_model import CLASSES, DEFAULT_SPEC, ROAD_CLASSES, TASK
from signlane.onnx_model import make_metadata


def export_lanes(ckpt: str | Path, out: str | Path, metrics: dict | None = None, tol: float = 1e-4) -> dict:
    """Export a lanes checkpoint; returns a report (parity, size, parameters). The metadata's data
    hash and val scores come from the checkpoint itself, plus the run's report.json (marking F1
    within 2 px) while the run folder is there; `metrics` adds to them."""
    from signlane_train.lane_net import count_parameters
    from signlane_train.lane_task import LaneTask
    ckpt, out = Path(ckpt), Path(out)
    task = load_task(ckpt, LaneTask, "lanes")
    spec = DEFAULT_SPEC
    info = training_info(ckpt)
    metrics = run_metrics(ckpt, info, metrics)
    # a road model's classes say so: the runtime reads its second head from them (seg_model)
    classes = list(ROAD_CLASSES if task.hparams.get("drivable", False) else CLASSES)
    heads = {"lane_marking": [0, 1]} | ({"drivable": [2, 3]} if len(classes) == 4 else {})
    meta = make_metadata(TASK, classes, spec, info["data_hash"], metrics,
                         {"arch": f"LaneSegNet width {task.hparams.width}"
                                  + (" scene" if task.hparams.get("scene", False) else ""), "checkpoint": ckpt.name,
                          "output": json.dumps({"size": "input", "classes": classes, "kind": "logits",
                                                "heads": heads})})
    report = export_onnx(task.net, (1, 3, spec.height, spec.width), out, meta, tol=tol)
    report.update({"parameters": count_parameters(task.net), "data_hash": info["data_hash"], "metrics": metrics})
    return report
