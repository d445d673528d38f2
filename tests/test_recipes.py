"""The model cards' recipes, shrunk: they write runs/ and data/ only, never the shipped models
(shipping is `signlane ship`); a checkpoint exports alone, from any folder, after its data is
gone; the data hash is of the data's content; the metadata carries the validation scores."""
import hashlib
import json
import shlex
import shutil
from pathlib import Path

import onnx
import pytest

from signlane.cli import main
from signlane.ship import MODELS_DIR

# a recipe's flags made small enough for a test: few frames, one epoch, no worker processes
SMALL = {"--n": {"signs": "140", "lanes": "40"}, "--epochs": "1", "--workers": "1", "--patience": "1"}


def shipped_models() -> dict[str, str]:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(MODELS_DIR.iterdir())}


def shrunk(command: str, kind: str) -> list[str]:
    argv = shlex.split(command)
    assert argv[0] == "signlane", command
    argv = argv[1:]
    for i, a in enumerate(argv[:-1]):
        if a in SMALL:
            v = SMALL[a]
            argv[i + 1] = v[kind] if isinstance(v, dict) else v
    if argv[0] == "train":
        argv += ["--workers", "0", "--batch-size", "16"]  # the last of a repeated flag wins
    return argv


def run_recipe(kind: str, where: Path, monkeypatch) -> dict:
    """The card's gen, train and export commands (and its quantization, where it has one), shrunk,
    run in `where` (as a user in a fresh clone runs them from its root); returns the card."""
    card = json.loads((MODELS_DIR / f"{kind}.json").read_text())
    monkeypatch.chdir(where)
    for section in ("data", "training", "export", "quantization"):
        if section in card:
            assert main(shrunk(card[section]["command"], kind)) == 0, card[section]["command"]
    return card


@pytest.fixture(scope="module")
def sign_recipe(tmp_path_factory):
    import signlane_train.signs  # noqa: F401  (Lightning's loggers keep the stderr of their first import)
    before = shipped_models()
    where = tmp_path_factory.mktemp("clone")
    with pytest.MonkeyPatch.context() as mp:
        card = run_recipe("signs", where, mp)
    return where, card, before


def test_the_sign_recipe_writes_runs_and_data_only(sign_recipe):
    where, card, before = sign_recipe
    assert shipped_models() == before
    assert "signlane/models" not in json.dumps(card)
    assert (where / "runs/signs/signs.onnx").is_file() and (where / "data/signs/manifest.json").is_file()
    shipped = shlex.split(card["ship"]["command"])[2]  # what the card's ship step ships: the recipe made it
    assert (where / shipped).is_file()
    assert sorted(p.name for p in where.iterdir()) == ["data", "runs"]


def test_the_lane_recipe_writes_runs_and_data_only(tmp_path, monkeypatch):
    before = shipped_models()
    card = run_recipe("lanes", tmp_path, monkeypatch)
    assert shipped_models() == before
    assert "signlane/models" not in json.dumps(card)
    out = shlex.split(card["export"]["command"])
    assert (tmp_path / out[out.index("--out") + 1]).is_file()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["data", "runs"]


def test_export_refuses_the_models_folder_and_ship_is_the_explicit_step(sign_recipe, tmp_path, capsys):
    where, _, before = sign_recipe
    ckpt, model = where / "runs/signs/checkpoints/best.ckpt", where / "runs/signs/signs.onnx"
    capsys.readouterr()
    assert main(["export", "signs", str(ckpt), "--out", str(MODELS_DIR / "signs.onnx")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "signlane ship" in err[0] and str(MODELS_DIR / "signs.onnx") in err[0]
    assert shipped_models() == before
    into = tmp_path / "models"
    assert main(["ship", str(model), "--as", "signs", "--into", str(into)]) == 0
    report = json.loads(capsys.readouterr().out)
    assert (into / "signs.onnx").read_bytes() == model.read_bytes()
    assert report["sha256"] == hashlib.sha256(model.read_bytes()).hexdigest() and report["metrics"]["val_acc"] > 0
    card = json.loads((into / "signs.json").read_text())  # the card now describes the shipped file
    assert card["sha256"] == report["sha256"] and card["metrics"] == report["metrics"] and card["replaced"] is None
    assert main(["ship", str(model), "--as", "signs", "--into", str(into / "again")]) == 0
    (into / "again" / "signs.json").write_text(json.dumps({"model": "old", "replaced": {"x": 1}}))
    assert main(["ship", str(model), "--as", "signs", "--into", str(into / "again")]) == 0
    assert json.loads((into / "again" / "signs.json").read_text())["replaced"] == {"model": "old"}
    assert main(["ship", str(model), "--as", "lanes", "--into", str(into)]) == 2  # a sign model is no lane model
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "signs.onnx" in err[0] and "lane-segmentation" in err[0]
    assert not (into / "lanes.onnx").exists() and shipped_models() == before


def test_a_checkpoint_exports_alone_from_any_folder(sign_recipe, tmp_path, monkeypatch, capsys):
    from signlane_data.content_hash import content_hash
    where, card, _ = sign_recipe
    clone = tmp_path / "clone"
    shutil.copytree(where / "data", clone / "data")
    expected = content_hash([clone / "data/signs"])
    monkeypatch.chdir(clone)  # trained as the card says, from the clone's root (a relative data path)
    assert main(shrunk(card["training"]["command"], "signs")) == 0
    lone = tmp_path / "elsewhere" / "best.ckpt"  # no run folder, no config.json beside it
    lone.parent.mkdir()
    shutil.move(clone / "runs/signs/checkpoints/best.ckpt", lone)
    monkeypatch.chdir(tmp_path)
    shutil.rmtree(clone)  # the data and the run are gone
    other = tmp_path / "another"
    other.mkdir()
    monkeypatch.chdir(other)
    capsys.readouterr()
    assert main(["export", "signs", str(lone), "--out", "model.onnx"]) == 0
    meta = {p.key: p.value for p in onnx.load("model.onnx").metadata_props}
    assert meta["signlane.data_hash"] == expected
    metrics = json.loads(meta["signlane.metrics"])
    assert 0 < metrics["val_acc"] <= 1 and 0 <= metrics["val_non_sign_accepted"] <= 1
    assert {f"val_recall_{c}" for c in ("stop", "left", "unknown")} <= set(metrics)
    capsys.readouterr()
    assert main(["export", "signs", str(lone), "--out", "q.onnx", "--int8"]) == 2  # int8 calibrates on the data
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "data/signs" in err[0] and not Path("q.onnx").exists()


def test_the_data_hash_is_of_the_content(sign_recipe, tmp_path):
    from signlane_data.content_hash import content_hash
    where, _, _ = sign_recipe
    data = where / "data/signs"
    a, b = tmp_path / "a", tmp_path / "b"
    shutil.copytree(data, a)
    shutil.copytree(data, b)
    manifest = json.loads((b / "manifest.json").read_text())
    manifest["created"] = "2001-01-01T00:00:00+00:00"  # made at another time: the same data
    (b / "manifest.json").write_text(json.dumps(manifest))
    (b / "preview.png").write_bytes(b"a picture for people")
    assert content_hash([a]) == content_hash([b]) == content_hash([data])
    crop = sorted((b / "stop").glob("*.png"))[0]
    crop.write_bytes(crop.read_bytes() + b"\0")
    assert content_hash([b]) != content_hash([a])
    meta = {p.key: p.value for p in onnx.load(str(where / "runs/signs/signs.onnx")).metadata_props}
    assert meta["signlane.data_hash"] == content_hash([data])
