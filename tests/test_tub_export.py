"""`signlane export-drive`: a real drive recording (a short lockstep drive on via_town through the
drive server with --record) written as a Donkey Car tub (datastore v2) and read back."""
import json
import shutil
import subprocess
import sys
from dataclasses import replace

import cv2
import pytest

from signlane.cli import main as cli_main
from signlane.config import Config
from signlane.sim.drive_record import RecordError, read_recording
from signlane.sim.server import DriveServer, ServerOptions
from signlane.sim.simulator import SimConfig, Simulator, run_client
from signlane.tub import DEFAULT_MAX_LEN, TubError, export_drive_tub, read_tub
from signlane.world.maps import load_track

W, H = 320, 240
INPUTS = ["cam/image_array", "user/angle", "user/throttle", "user/mode", "car/speed"]
TYPES = ["image_array", "float", "float", "str", "float"]


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """0.7 simulated seconds of via_town at 30 frames/s: 21 recorded frames from one client."""
    rec = tmp_path_factory.mktemp("drive") / "rec"
    cfg = replace(Config(), signs=replace(Config().signs, enabled=False))
    sim = Simulator(load_track("via_town"), SimConfig(width=W, height=H, max_seconds=0.7))
    with DriveServer(cfg, ServerOptions(port=0, record=rec, sync_signs=True)) as srv:
        run_client(sim, srv.url, lockstep=True)
    assert len(read_recording(rec).frames) == 21
    return rec


def recorded(rec):
    return [json.loads(x) for x in (rec / "drive.jsonl").read_text().splitlines()]


def catalog_lines(path):
    return path.read_text().splitlines(keepends=True)


def test_tub_layout_and_records(recording, tmp_path):
    out = tmp_path / "tub"
    done = export_drive_tub(recording, out, max_len=8, progress=False)
    assert (done.frames, done.catalogs, done.sessions, done.folder) == (21, 3, 1, out)
    lines = (out / "manifest.json").read_text().splitlines()
    assert len(lines) == 5
    inputs, types, metadata, meta, books = (json.loads(x) for x in lines)
    assert inputs == INPUTS and types == TYPES and len(inputs) == len(types)
    assert metadata["source"] == "signlane drive recording" and all(isinstance(v, str) for v in metadata.values())
    assert isinstance(meta["created_at"], float)
    assert meta["sessions"]["last_id"] == 0 and meta["sessions"]["all_full_ids"] == [meta["sessions"]["last_full_id"]]
    on_disk = sorted((p.name for p in out.glob("catalog_*.catalog")), key=lambda n: int(n[8:-8]))
    assert books == {"paths": on_disk, "current_index": 21, "max_len": 8, "deleted_indexes": []}
    assert on_disk == ["catalog_0.catalog", "catalog_1.catalog", "catalog_2.catalog"]

    records, start = [], 0
    for name in books["paths"]:  # split at the limit, each catalog with its own manifest
        cat = catalog_lines(out / name)
        cm_lines = (out / name).with_suffix(".catalog_manifest").read_text().splitlines()
        assert len(cm_lines) == 1
        cm = json.loads(cm_lines[0])
        assert set(cm) == {"created_at", "line_lengths", "path", "start_index"} and cm["path"] == name
        assert cm["start_index"] == start and cm["line_lengths"] == [len(x) for x in cat]
        records += [json.loads(x) for x in cat]
        start += len(cat)
    assert [len(catalog_lines(out / n)) for n in on_disk] == [8, 8, 5]

    frames = recorded(recording)
    assert [r["_index"] for r in records] == list(range(21))
    session = records[0]["_session_id"]
    assert session == meta["sessions"]["last_full_id"] and all(r["_session_id"] == session for r in records)
    stamps = [r["_timestamp_ms"] for r in records]
    assert all(isinstance(s, int) for s in stamps) and stamps == sorted(stamps)
    assert stamps[-1] - stamps[0] == round(1000 * (frames[-1]["t"] - frames[0]["t"]))
    for i, (r, f) in enumerate(zip(records, frames)):
        assert set(r) == set(INPUTS) | {"_index", "_session_id", "_timestamp_ms"}
        assert r["cam/image_array"] == f"{i}_cam_image_array_.jpg"
        assert r["user/angle"] == f["command"]["steering"] and r["user/throttle"] == f["command"]["throttle"]
        assert r["car/speed"] == f["telemetry"]["speed_mps"] and r["user/mode"] == "user"
        img = out / "images" / r["cam/image_array"]
        assert img.read_bytes() == (recording / f["image"]).read_bytes()  # copied, not re-encoded
        assert cv2.imread(str(img)).shape == (H, W, 3)
    assert len(list((out / "images").iterdir())) == 21
    assert read_tub(out).records == tuple(records)  # the reader sees what donkeycar would
    assert not list(tmp_path.glob(".*"))  # no temporary folder left beside it


def test_size_resizes_to_donkeycars_default(recording, tmp_path):
    out = tmp_path / "tub"
    export_drive_tub(recording, out, size=(160, 120), progress=False)
    tub = read_tub(out)
    assert tub.metadata["image_size"] == "160x120" and len(tub.records) == 21
    assert [cv2.imread(str(tub.image_path(r))).shape for r in tub.records] == [(120, 160, 3)] * 21


def test_each_client_is_one_session_in_order(recording, tmp_path):
    """Two connections' frames interleaved in drive.jsonl: two sessions, each one's frames together."""
    rec = tmp_path / "two"
    shutil.copytree(recording, rec)
    frames = recorded(recording)
    for i, f in enumerate(frames):
        f["client"] = 1 + i % 2
    (rec / "drive.jsonl").write_text("".join(json.dumps(f) + "\n" for f in frames))
    tub = read_tub(export_drive_tub(rec, tmp_path / "tub", progress=False).folder)
    ids = tub.manifest_metadata["sessions"]["all_full_ids"]
    assert len(ids) == 2 and ids[0].endswith("_0") and ids[1].endswith("_1")
    assert [r["_session_id"] for r in tub.records] == [ids[0]] * 11 + [ids[1]] * 10
    assert [r["user/angle"] for r in tub.records] == [f["command"]["steering"] for f in frames[::2] + frames[1::2]]
    assert [r["_index"] for r in tub.records] == list(range(21))
    assert tub.catalogs["paths"] == ["catalog_0.catalog"] and tub.catalogs["max_len"] == DEFAULT_MAX_LEN == 1000


def test_cli_refuses_an_incomplete_recording(recording, tmp_path, capsys):
    rec = tmp_path / "partial"
    shutil.copytree(recording, rec)
    (rec / "manifest.json").unlink()  # what a killed server leaves
    assert cli_main(["export-drive", str(rec), "--out", str(tmp_path / "tub")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "incomplete recording" in err and str(rec) in err
    assert not (tmp_path / "tub").exists()


def test_cli_refuses_a_non_empty_output_unless_forced(recording, tmp_path, capsys):
    out = tmp_path / "tub"
    out.mkdir()
    (out / "keep.txt").write_text("x")
    assert cli_main(["export-drive", str(recording), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "not empty" in err and "--force" in err
    assert [p.name for p in out.iterdir()] == ["keep.txt"]

    assert cli_main(["export-drive", str(recording), "--out", str(out), "--format", "tub", "--force"]) == 0
    summary = capsys.readouterr().out.strip().splitlines()
    assert summary == [f"wrote 21 frames (1 session(s), 1 catalog file(s)) as a Donkey Car tub in {out}"]
    assert not (out / "keep.txt").exists() and len(read_tub(out).records) == 21
    assert sorted(p.name for p in tmp_path.iterdir()) == ["tub"]  # nothing left beside it
    # --force never replaces the recording itself
    assert cli_main(["export-drive", str(recording), "--out", str(recording), "--force"]) == 2
    assert "replace the recording" in capsys.readouterr().err
    assert (recording / "manifest.json").exists()


def test_a_broken_frame_leaves_no_tub(recording, tmp_path):
    rec = tmp_path / "broken"
    shutil.copytree(recording, rec)
    (rec / "images" / "c1-000005.jpg").unlink()
    with pytest.raises(RecordError, match="c1-000005"):
        export_drive_tub(rec, tmp_path / "tub", progress=False)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["broken"]  # no tub, no temporary


def test_reader_checks_catalog_manifests(recording, tmp_path):
    out = export_drive_tub(recording, tmp_path / "tub", max_len=8, progress=False).folder
    cm = out / "catalog_1.catalog_manifest"
    meta = json.loads(cm.read_text())
    cm.write_text(json.dumps({**meta, "start_index": 0}) + "\n")
    with pytest.raises(TubError, match="catalog_1"):
        read_tub(out)


def test_export_needs_no_torch():
    code = ("import sys, signlane.tub\nfrom signlane.cli import main\n"
            "try:\n    main(['export-drive', '--help'])\nexcept SystemExit:\n    pass\n"
            "print('torch' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert "donkeycar" in out and out.strip().splitlines()[-1] == "False"


# donkeycar's own reader, run in its own process (importing donkeycar prints a banner, configures
# logging and raises the recursion limit): Tub iterates the catalogs, TubRecord loads the images
# as its training pipeline does. `.ci/run` installs donkeycar without its heavy dependencies.
DONKEY_READS = """
import json, sys
from donkeycar.config import Config
from donkeycar.parts.tub_v2 import Tub
from donkeycar.pipeline.types import TubRecord
tub = Tub(sys.argv[1], read_only=True)
cfg = Config()
cfg.IMAGE_W, cfg.IMAGE_H, cfg.IMAGE_DEPTH = 320, 240, 3
out = []
for rec in tub:
    image = TubRecord(cfg, tub.base_path, rec).image()
    out.append({"angle": rec["user/angle"], "throttle": rec["user/throttle"], "mode": rec["user/mode"],
                "index": rec["_index"], "shape": list(image.shape), "mean": float(image.mean())})
print("RESULT " + json.dumps({"inputs": tub.manifest.inputs, "types": tub.manifest.types, "n": len(tub),
                               "records": out}))
"""


def test_donkeycars_own_tub_reader_reads_the_export(recording, tmp_path):
    import importlib.util
    if importlib.util.find_spec("donkeycar") is None:
        pytest.skip("donkeycar is not installed (.ci/run installs it)")
    out = tmp_path / "tub"
    export_drive_tub(recording, out, max_len=8, progress=False)  # three catalogs
    done = subprocess.run([sys.executable, "-c", DONKEY_READS, str(out)], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    got = json.loads(done.stdout[done.stdout.index("RESULT ") + 7:])
    assert got["inputs"] == INPUTS and got["types"] == TYPES and got["n"] == 21
    frames = recorded(recording)
    assert [r["index"] for r in got["records"]] == list(range(21))
    assert [r["angle"] for r in got["records"]] == [f["command"]["steering"] for f in frames]
    assert [r["throttle"] for r in got["records"]] == [f["command"]["throttle"] for f in frames]
    assert {r["mode"] for r in got["records"]} == {"user"}
    for r, f in zip(got["records"], frames):  # the very pixels of the recorded frame, RGB
        assert r["shape"] == [H, W, 3]
        assert abs(r["mean"] - float(cv2.imread(str(recording / f["image"])).mean())) < 0.5
