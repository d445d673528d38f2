"""ONNX export shared by every model: export, metadata, onnx.checker, onnxruntime-vs-torch parity,
int8 quantization. Export fails loudly: a file that does not check or match torch raises."""
from __future__ import annotations

import json
import logging
import os
import tempfile
import warnings
from pathlib import Path

import numpy as np
import onnx
import torch

from signlane_data.content_hash import content_hash


class ExportError(Exception):
    pass


def run_dir_of(ckpt: Path) -> Path:
    """The training run folder of a checkpoint (<run>/checkpoints/x.ckpt)."""
    return ckpt.parent.parent if ckpt.parent.name == "checkpoints" else ckpt.parent


def training_info(ckpt: Path) -> dict:
    """{"data": [folders], "data_hash": str, "metrics": {name: float}} of a checkpoint: what
    training stored in it (signlane_train.run_info), so export needs neither the run folder nor
    the data. A checkpoint from before that falls back on its run's config.json (data paths as
    written then) and hashes those folders where they still exist ("unknown" where not)."""
    from signlane_train.run_info import KEY
    try:
        raw = torch.load(ckpt, map_location="cpu", weights_only=False)
    except Exception as e:  # a truncated zip, a pickle of something else: one line, not a traceback
        raise ValueError(f"{ckpt}: not a readable checkpoint ({type(e).__name__}: {str(e)[:120]})") from None
    if isinstance(raw, dict) and isinstance(raw.get(KEY), dict):
        return raw[KEY]
    cfg_path = run_dir_of(ckpt) / "config.json"
    roots = list(json.loads(cfg_path.read_text()).get("data", [])) if cfg_path.exists() else []
    present = bool(roots) and all(Path(r).is_dir() for r in roots)
    return {"data": roots, "data_hash": content_hash(roots) if present else "unknown", "metrics": {}}


def load_task(ckpt: Path, task_cls, what: str):
    """The Lightning task of a checkpoint, in eval mode on the CPU; one ValueError line for a
    missing file or a checkpoint of another task."""
    if not ckpt.is_file():
        raise ValueError(f"{ckpt}: checkpoint not found")
    try:
        return task_cls.load_from_checkpoint(str(ckpt), map_location="cpu").eval()
    except (KeyError, RuntimeError, TypeError) as e:
        raise ValueError(f"{ckpt}: not a {what} checkpoint ({type(e).__name__}: {str(e)[:120]})") from None


def run_metrics(ckpt: Path, info: dict, extra: dict | None = None) -> dict:
    """The metadata's metrics: what the checkpoint stored, the run's report.json val_ scores
    while the run folder is there, then `extra`."""
    report = run_dir_of(ckpt) / "report.json"
    scored = json.loads(report.read_text()) if report.exists() else {}
    return {**info.get("metrics", {}), **{k: v for k, v in scored.items() if k.startswith("val_")}, **(extra or {})}


def present_data(info: dict) -> list[str] | None:
    """The training folders when all of them still exist (for checks on the val split), else None."""
    roots = info.get("data") or []
    return roots if roots and all(Path(r).is_dir() for r in roots) else None


def _session(path: str | Path):
    import onnxruntime as ort
    opts = ort.SessionOptions()
    opts.log_severity_level = 3
    return ort.InferenceSession(str(path), opts, providers=["CPUExecutionProvider"])


def export_onnx(model: torch.nn.Module, input_shape: tuple[int, ...], path: str | Path, metadata: dict[str, str],
                tol: float = 1e-4, opset: int = 17) -> dict:
    """Export with a dynamic batch axis, add metadata, check, compare with torch; atomic write."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    model = model.eval().cpu()
    fd, tmp = tempfile.mkstemp(suffix=".onnx", dir=path.parent)
    os.close(fd)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the TorchScript exporter's deprecation notice
            torch.onnx.export(model, (torch.zeros(*input_shape),), tmp, input_names=["input"], output_names=["output"],
                              dynamic_axes={"input": {0: "batch"}, "output": {0: "batch"}}, dynamo=False,
                              opset_version=opset)
        proto = onnx.load(tmp)
        set_metadata(proto, metadata)
        onnx.checker.check_model(proto)
        onnx.save(proto, tmp)
        parity = check_parity(model, tmp, input_shape, tol)
        os.chmod(tmp, 0o644)  # mkstemp makes it private; a model file is for everyone to read
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return {"parity_max_abs": parity, "bytes": path.stat().st_size}


def set_metadata(proto: onnx.ModelProto, metadata: dict[str, str]) -> None:
    keep = [p for p in proto.metadata_props if p.key not in metadata]
    del proto.metadata_props[:]
    proto.metadata_props.extend(keep)
    for k, v in metadata.items():
        proto.metadata_props.add(key=k, value=str(v))


def check_parity(model: torch.nn.Module, onnx_path: str | Path, input_shape: tuple[int, ...], tol: float) -> float:
    """Max |torch - onnxruntime| over fixed seeded inputs at batch 1 and 5; raises above tol."""
    sess = _session(onnx_path)
    g = torch.Generator().manual_seed(0)
    worst = 0.0
    for batch in (1, 5):
        x = torch.randn((batch, *input_shape[1:]), generator=g)
        with torch.no_grad():
            ref = model(x).numpy()
        got = sess.run(None, {"input": x.numpy()})[0]
        worst = max(worst, float(np.max(np.abs(ref - got))))
    if not worst <= tol:
        raise ExportError(f"{onnx_path}: onnxruntime output differs from torch by {worst:.2e} (> {tol:.0e})")
    return worst


def quantize_int8(src: str | Path, dst: str | Path, calibration: list[np.ndarray],
                  extra_metadata: dict[str, str] | None = None) -> None:
    """Static int8 (QDQ) quantization calibrated on the given input batches; metadata kept (plus
    `extra_metadata`, full keys)."""
    from onnxruntime.quantization import CalibrationDataReader, QuantFormat, QuantType, quantize_static
    from onnxruntime.quantization.shape_inference import quant_pre_process

    class Reader(CalibrationDataReader):
        def __init__(self):
            self.it = iter(calibration)

        def get_next(self):
            x = next(self.it, None)
            return None if x is None else {"input": x}

    dst = Path(dst)
    fd, tmp = tempfile.mkstemp(suffix=".onnx", dir=dst.parent)
    os.close(fd)
    pre = tmp[:-len(".onnx")] + "_pre.onnx"
    try:
        # onnxruntime's own preparation (shapes inferred, graph optimised) before the ranges are
        # taken: what its quantizer asks for, and it warns without it
        logging.getLogger("onnxruntime.quantization.shape_inference").setLevel(logging.WARNING)  # its progress notes
        quant_pre_process(str(src), pre)
        quantize_static(pre, tmp, Reader(), quant_format=QuantFormat.QDQ, activation_type=QuantType.QUInt8,
                        weight_type=QuantType.QInt8, per_channel=True)
        proto = onnx.load(tmp)
        set_metadata(proto, {**{p.key: p.value for p in onnx.load(str(src)).metadata_props}, **(extra_metadata or {})})
        onnx.checker.check_model(proto)
        onnx.save(proto, tmp)
        os.chmod(tmp, 0o644)
        os.replace(tmp, dst)
    finally:
        for leftover in (tmp, pre):
            if os.path.exists(leftover):
                os.unlink(leftover)
