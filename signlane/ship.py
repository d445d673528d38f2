"""Shipping a model: the one step that replaces a default model in signlane/models/.

Recipes train and export into runs/ and out/; with an editable install every later command would
silently pick up a model written into the package, so export refuses that folder and shipping is
this explicit step. The file is loaded as the runtime loads it (contract, graph, a test batch)
before it is copied in (temp file, then rename), so a model that would not drive is never shipped.
"""
from __future__ import annotations

import hashlib
import json
from datetime import datetime, timezone
from pathlib import Path

from signlane.fileio import atomic_write_bytes, atomic_write_json

MODELS_DIR = Path(__file__).resolve().parent / "models"
KINDS = ("signs", "lanes", "pilot")


class ShipError(ValueError):
    pass


def in_models_dir(path: str | Path, models_dir: Path = MODELS_DIR) -> bool:
    """Whether writing `path` would replace (or add to) the package's shipped models."""
    return Path(path).resolve().parent == models_dir.resolve()


def _load(path: Path, kind: str):
    from signlane.onnx_model import ModelError
    try:
        if kind == "signs":
            from signlane.signs.classifier import SignClassifier
            return SignClassifier(path).model
        if kind == "pilot":
            from signlane.pilot import PilotModel
            return PilotModel(path).model
        from signlane.lanes.seg_model import LaneSegModel
        return LaneSegModel(path).model
    except ModelError as e:
        raise ShipError(str(e)) from None


def ship_model(src: str | Path, kind: str, models_dir: Path = MODELS_DIR) -> dict:
    """Check `src` as a `kind` model and copy it to models_dir/<kind>.onnx; returns what was
    shipped (path, sha256, the model's data hash and metrics)."""
    src = Path(src)
    if kind not in KINDS:
        raise ShipError(f"--as {kind!r}: ship one of {', '.join(KINDS)}")
    if not src.is_file():
        raise ShipError(f"{src}: model file not found")
    dst = Path(models_dir) / f"{kind}.onnx"
    if dst.exists() and src.resolve() == dst.resolve():
        raise ShipError(f"{src} is already the shipped {kind} model")
    model = _load(src, kind)
    data = src.read_bytes()
    sha = hashlib.sha256(data).hexdigest()
    card = dst.with_suffix(".json")
    new_card = _card(kind, src, sha, model, card)
    atomic_write_bytes(dst, data)
    atomic_write_json(card, new_card)
    return {"shipped": str(dst), "from": str(src), "sha256": sha,
            "data_hash": model.meta.get("data_hash", "unknown"), "metrics": model.metrics, "card": str(card)}


def _card(kind: str, src: Path, sha: str, model, old_path: Path) -> dict:
    """The model card for a shipped file: what the file itself says (task, classes, input,
    data hash, the metrics its export recorded) and where it came from; the card of the model it
    replaces is kept under "replaced" (its recipe and test-set numbers are that model's, not
    this one's: measure this one with `signlane eval` and add them)."""
    try:
        old = json.loads(old_path.read_text()) if old_path.is_file() else None
    except (OSError, ValueError):
        old = None
    if isinstance(old, dict):
        old.pop("replaced", None)  # one generation back is enough to see what changed
    return {"model": f"{kind}.onnx", "task": model.meta.get("task"), "classes": list(model.classes),
            "input": json.loads(model.input.to_json()),
            "status": "shipped", "status_note": f"shipped by `signlane ship {src} --as {kind}` on "
            f"{datetime.now(timezone.utc).date().isoformat()}; metrics are the ones its export recorded",
            "sha256": sha, "data_hash": model.meta.get("data_hash", "unknown"), "metrics": model.metrics,
            "shipped_from": str(src.resolve()), "replaced": old}
