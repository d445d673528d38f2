"""ONNX models with their contract in metadata_props, run with onnxruntime.

Every signlane model carries (keys prefixed `signlane.`): `task`, `contract` (version of this
contract), `classes` (JSON list, in output order), `input` (JSON: size [w, h], color, layout,
scale, mean, std), `data_hash`, `metrics` (JSON). The loader refuses a file whose contract it
does not understand, or whose graph does not keep it (one float32 input of the stated size,
an output with one channel per class), with one line naming the file and the problem.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

CONTRACT_VERSION = "1"
PREFIX = "signlane."
COLORS = ("RGB", "BGR", "HSV")  # HSV: S3's PilotNet input (its scale/std bring H 0..179 to [0, 1])
_CONVERT = {"RGB": cv2.COLOR_BGR2RGB, "HSV": cv2.COLOR_BGR2HSV}


class ModelError(Exception):
    """A model file that cannot be used: str(e) names the file and the problem."""


@dataclass(frozen=True)
class InputSpec:
    width: int
    height: int
    color: str  # "RGB", "BGR" or "HSV" (OpenCV's: H 0..179, S and V 0..255)
    layout: str  # "NCHW"
    scale: float  # multiply uint8 pixels by this first
    mean: tuple[float, float, float]
    std: tuple[float, float, float]

    def to_json(self) -> str:
        return json.dumps({"size": [self.width, self.height], "color": self.color, "layout": self.layout,
                           "scale": self.scale, "mean": list(self.mean), "std": list(self.std)})

    @classmethod
    def from_json(cls, text: str, where: str) -> "InputSpec":
        try:
            d = json.loads(text)
            spec = cls(int(d["size"][0]), int(d["size"][1]), str(d["color"]), str(d["layout"]), float(d["scale"]),
                       tuple(float(v) for v in d["mean"]), tuple(float(v) for v in d["std"]))
        except (ValueError, KeyError, TypeError, IndexError) as e:
            raise ModelError(f"{where}: metadata 'input' is malformed ({e})") from None
        if spec.color not in COLORS or spec.layout != "NCHW" or min(spec.width, spec.height) < 4 \
                or len(spec.mean) != 3 or len(spec.std) != 3 or min(spec.std) <= 0:
            raise ModelError(f"{where}: metadata 'input' is not understood: {text}")
        return spec


def halved(image: np.ndarray, width: int, height: int) -> np.ndarray:
    """`image` halved (2x2 box average) while it is an even number of times `width` x `height`
    in both directions: an area resize's box average of an exact factor, made as halvings (a
    2x2 average is OpenCV's fast path: 640x480 to 160x120 in 0.09 ms where one 4x area resize
    takes 0.32), within half a grey level of it (each halving rounds to uint8)."""
    h, w = image.shape[:2]
    while w >= 2 * width and h >= 2 * height and w % (2 * width) == 0 and h % (2 * height) == 0:
        w, h = w // 2, h // 2
        image = cv2.resize(image, (w, h), interpolation=cv2.INTER_AREA)
    return image


def prepare_input(images_bgr: list[np.ndarray], spec: InputSpec, what: str = "image") -> np.ndarray:
    """uint8 BGR images (H, W, 3) of any size -> float32 (N, 3, spec.height, spec.width) model
    input: resized (area when shrinking), colour order as the spec says, (x * scale - mean) / std.
    The one place pixels become input, for every model: training, export parity and runtime."""
    out = np.empty((len(images_bgr), 3, spec.height, spec.width), np.float32)
    # (x * scale - mean) / std as one multiply-add per pixel
    gain = (spec.scale / np.array(spec.std, np.float32)).reshape(3, 1, 1)
    bias = (np.array(spec.mean, np.float32) / np.array(spec.std, np.float32)).reshape(3, 1, 1)
    for i, f in enumerate(images_bgr):
        if f.ndim != 3 or f.shape[2] != 3 or f.dtype != np.uint8:
            raise ValueError(f"{what} {i}: expected uint8 (H, W, 3) BGR, got {f.dtype} {f.shape}")
        shrink = f.shape[0] > spec.height or f.shape[1] > spec.width
        r = cv2.resize(halved(f, spec.width, spec.height), (spec.width, spec.height),
                       interpolation=cv2.INTER_AREA if shrink else cv2.INTER_LINEAR)
        if spec.color != "BGR":
            r = cv2.cvtColor(r, _CONVERT[spec.color])
        x = out[i]
        np.multiply(r.transpose(2, 0, 1), gain, out=x, casting="unsafe")
        x -= bias
    return out


def make_metadata(task: str, classes: list[str], spec: InputSpec, data_hash: str, metrics: dict,
                  extra: dict[str, str] | None = None) -> dict[str, str]:
    meta = {"task": task, "contract": CONTRACT_VERSION, "classes": json.dumps(classes), "input": spec.to_json(),
            "data_hash": data_hash, "metrics": json.dumps(metrics)}
    meta.update(extra or {})
    return {PREFIX + k: v for k, v in meta.items()}


def _dims(shape) -> str:
    return "(" + ", ".join(str(d) if d is not None else "?" for d in shape) + ")"


class OnnxModel:
    """An onnxruntime session plus the contract read from the file's metadata.

    `output_rank` is the rank of the task's first output, (N, classes) = 2 or (N, classes, h, w)
    = 4; the graph is checked against the contract at load, and run once on a test batch, so a
    mismatch is one line here rather than a traceback on some later frame."""

    def __init__(self, path: str | Path, task: str, threads: int = 1, output_rank: int = 2):
        import onnxruntime as ort
        self.path = Path(path)
        where = str(self.path)
        if not self.path.is_file():
            raise ModelError(f"{where}: model file not found")
        opts = ort.SessionOptions()
        opts.intra_op_num_threads = threads
        opts.inter_op_num_threads = 1
        opts.log_severity_level = 3
        try:
            self.session = ort.InferenceSession(where, opts, providers=["CPUExecutionProvider"])
        except Exception as e:  # onnxruntime raises its own exception types for corrupt files
            first = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
            raise ModelError(f"{where}: not a loadable ONNX model ({first[:200]})") from None
        meta = self.session.get_modelmeta().custom_metadata_map
        self.meta = {k[len(PREFIX):]: v for k, v in meta.items() if k.startswith(PREFIX)}
        if self.meta.get("task") != task:
            raise ModelError(f"{where}: metadata task is {self.meta.get('task')!r}, expected {task!r} "
                             "(not a signlane model for this job)")
        if self.meta.get("contract") != CONTRACT_VERSION:
            raise ModelError(f"{where}: model contract {self.meta.get('contract')!r} is not supported "
                             f"(this signlane reads contract {CONTRACT_VERSION})")
        try:
            self.classes = [str(c) for c in json.loads(self.meta["classes"])]
        except (KeyError, ValueError, TypeError):
            raise ModelError(f"{where}: metadata 'classes' is missing or not a JSON list") from None
        self.input = InputSpec.from_json(self.meta.get("input", ""), where)
        self.input_name = self._check_input(where)
        self._check_output(where, output_rank)
        try:
            self.metrics = json.loads(self.meta.get("metrics", "{}"))
        except ValueError:
            self.metrics = {}

    def _check_input(self, where: str) -> str:
        """The graph's one input: float32 (N, 3, height, width) as the metadata says."""
        inputs = self.session.get_inputs()
        if len(inputs) != 1:
            raise ModelError(f"{where}: graph has {len(inputs)} inputs ({', '.join(i.name for i in inputs)}); "
                             "the contract is one image batch")
        inp = inputs[0]
        if inp.type != "tensor(float)":
            raise ModelError(f"{where}: graph input {inp.name!r} is {inp.type}, the contract is tensor(float)")
        want = (None, 3, self.input.height, self.input.width)
        shape = list(inp.shape or [])
        fixed_ok = all(not isinstance(d, int) or w is None or d == w for d, w in zip(shape, want))
        if len(shape) != 4 or not fixed_ok or isinstance(shape[0], int):
            raise ModelError(f"{where}: graph input {inp.name!r} is {_dims(shape)}; the metadata says "
                             f"(batch, 3, {self.input.height}, {self.input.width}) with a free batch size")
        return inp.name

    def _check_output(self, where: str, rank: int) -> None:
        """Run a batch of two blank images: the first output must be float (2, classes, ...)."""
        out = self.session.get_outputs()[0]
        if out.type != "tensor(float)":
            raise ModelError(f"{where}: graph output {out.name!r} is {out.type}, the contract is tensor(float)")
        x = np.zeros((2, 3, self.input.height, self.input.width), np.float32)
        try:
            y = np.asarray(self.session.run(None, {self.input_name: x})[0])
        except Exception as e:  # onnxruntime's own exception types
            first = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
            raise ModelError(f"{where}: graph fails on a test batch ({first[:200]})") from None
        n = len(self.classes)
        if y.ndim != rank or y.shape[0] != 2 or y.shape[1] != n:
            want = "(batch, classes)" if rank == 2 else "(batch, classes, h, w)"
            raise ModelError(f"{where}: graph output is {_dims(y.shape)} for a batch of 2; the contract is {want} "
                             f"with the {n} classes the metadata lists")

    def run(self, batch: np.ndarray) -> np.ndarray:
        return self.session.run(None, {self.input_name: batch})[0]
