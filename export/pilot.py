"""`signlane export pilot CKPT --out pilot.onnx`: the pilot as ONNX with its contract (task
"pilot", its outputs as classes, its HSV input), checked (onnx.checker) and compared with torch
(onnxruntime parity) or it raises; then loaded as the runtime loads it."""
from __future__ import annotations

import json
from pathlib import Path

from signlane.pilot import BRANCHED_CLASSES, PILOTNET_CLASSES, TASK, PilotModel
from signlane.onnx_model import make_metadata
from signlane_export.onnx_export import export_onnx, load_task, run_metrics, training_info


def export_pilot(ckpt: str | Path, out: str | Path, tol: float = 1e-4) -> dict:
    """Export a pilot checkpoint; returns a report (parity, size, parameters, metrics). The data
    hash and val scores come from the checkpoint, plus the run's report.json while it is there."""
    from signlane_train.pilot import spec_of
    from signlane_train.pilot_net import count_parameters
    from signlane_train.pilot_task import PilotTask
    ckpt, out = Path(ckpt), Path(out)
    task = load_task(ckpt, PilotTask, "pilot")
    arch = task.hparams.arch
    spec = spec_of(arch)
    classes = list(PILOTNET_CLASSES if arch == "pilotnet" else BRANCHED_CLASSES)
    info = training_info(ckpt)
    metrics = run_metrics(ckpt, info)
    name = "PilotNet (S3, NVIDIA)" if arch == "pilotnet" else f"SmallPilot width {task.hparams.width}"
    meta = make_metadata(TASK, classes, spec, info["data_hash"], metrics,
                         {"arch": name, "checkpoint": ckpt.name,
                          "output": json.dumps({"kind": "regression", "steering": "[-1, 1], + right",
                                                "speed": "m/s" if "speed" in classes else None})})
    report = export_onnx(task.net, (1, 3, spec.height, spec.width), out, meta, tol=tol)
    PilotModel(out)  # the runtime's own checks: contract, graph, a test batch
    report.update({"arch": arch, "classes": classes, "parameters": count_parameters(task.net),
                   "data_hash": info["data_hash"], "metrics": metrics})
    return report
