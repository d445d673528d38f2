"""`signlane infer`: outputs per the contract, and every malformed input handled in one line."""
import json

import cv2
import numpy as np
import pytest

from signlane.camera import via_camera
from signlane.cli import main
from signlane.video_out import VideoOut
from signlane.world.sampling import DriveSampler, FrameSampler, SamplerConfig
from track_helpers import track_with_stop_sign

KEYS = {"source", "frame", "width", "height", "lane", "signs", "control", "timing_ms"}
LANE_KEYS = {"method", "found", "offset", "heading", "curvature", "confidence", "left", "right"}


@pytest.fixture(scope="module")
def road_frames():
    """VIA-style frames from VIA's camera: what infer's defaults are for."""
    s = FrameSampler(3, SamplerConfig(effects="clean", randomise=False, style="via"))
    return [s.sample(i) for i in (0, 5, 10)]


@pytest.fixture(scope="module")
def painted_frames():
    """Painted-lane frames from another camera (90 degrees, 1.3 m, 10 degrees down)."""
    s = FrameSampler(3, SamplerConfig(effects="clean", randomise=False, style="painted"))
    return [s.sample(i) for i in (0, 5, 10)]


def _run(args, capsys):
    code = main(["infer", "--no-progress", *map(str, args)])
    out, err = capsys.readouterr()
    return code, out, err


def test_images_folder_json_and_annotated_output(tmp_path, road_frames, capsys):
    folder = tmp_path / "in"
    folder.mkdir()
    for i, smp in enumerate(road_frames):
        cv2.imwrite(str(folder / f"f{i}.png"), smp.image)
    out = tmp_path / "out"
    code, stdout, err = _run([folder, "--out", out, "--json", "-", "--save-masks"], capsys)
    assert code == 0, err
    recs = [json.loads(line) for line in stdout.splitlines()]
    # the contract's keys, and the camera infer measured the frames with (VIA's: they agree with it)
    assert len(recs) == 3 and all(set(r) == KEYS | {"camera"} and set(r["lane"]) == LANE_KEYS for r in recs)
    assert not any(r["camera"]["estimated"] for r in recs)
    assert sum(r["lane"]["confidence"] == 1.0 for r in recs) >= 2
    for r, smp in zip(recs, road_frames):
        assert r["width"] == 320 and r["height"] == 240
        assert smp.truth.camera == via_camera(320, 240)
        assert r["lane"]["found"]
        if r["lane"]["confidence"] == 1.0:  # both kerbs seen: the carriageway's middle is measured
            assert abs(r["lane"]["offset"] - smp.truth.offset) < 0.15
        else:  # one kerb (a bend's inner kerb out of view): the other is a width's guess, and says so
            assert r["lane"]["confidence"] <= 0.6
        assert -1 <= r["control"]["steering"] <= 1 and r["control"]["state"] == "cruise"
    for i in range(3):
        assert (out / f"f{i}.png").exists()
        mask = cv2.imread(str(out / f"f{i}_lane.png"), cv2.IMREAD_UNCHANGED)
        assert mask.shape == (240, 320) and set(np.unique(mask)) <= {0, 255} and mask.max() == 255
    assert "lanes found" in err and "frames" in err


def test_painted_lanes_from_another_camera_given_with_set(tmp_path, painted_frames, capsys):
    for i, smp in enumerate(painted_frames):
        cv2.imwrite(str(tmp_path / f"p{i}.png"), smp.image)
    cam = painted_frames[0].truth.camera
    sets = [f"camera.{k}={getattr(cam, k)}" for k in ("hfov_deg", "height_m", "pitch_deg")]
    code, stdout, err = _run([tmp_path, "--json", "-", *[a for kv in sets for a in ("--set", kv)]], capsys)
    assert code == 0, err
    recs = [json.loads(line) for line in stdout.splitlines()]
    assert len(recs) == 3
    for r, smp in zip(recs, painted_frames):
        assert r["lane"]["found"] and abs(r["lane"]["offset"] - smp.truth.offset) < 0.15
    # with VIA's camera assumed instead, the same frames read off (the camera matters; without
    # camera.estimate=off infer measures it: tests/test_camera_estimate.py)
    code, stdout, _ = _run([tmp_path, "--json", "-", "--set", "camera.estimate=off"], capsys)
    wrong = [json.loads(line)["lane"] for line in stdout.splitlines()]
    assert max(abs(w["offset"] - smp.truth.offset) if w["found"] else 1.0
               for w, smp in zip(wrong, painted_frames)) > 0.15


def test_video_in_annotated_video_out(tmp_path, road_frames, capsys):
    src = tmp_path / "clip.mp4"
    w = cv2.VideoWriter(str(src), cv2.VideoWriter_fourcc(*"mp4v"), 10, (320, 240))
    for smp in road_frames:
        w.write(smp.image)
    w.release()
    js = tmp_path / "clip.jsonl"
    code, _, err = _run([src, "--out", tmp_path / "o", "--json", js], capsys)
    assert code == 0, err
    recs = [json.loads(line) for line in js.read_text().splitlines()]
    assert [r["frame"] for r in recs] == [0, 1, 2]
    cap = cv2.VideoCapture(str(tmp_path / "o" / "clip.mp4"))
    assert cap.get(cv2.CAP_PROP_FRAME_COUNT) == 3


def test_every_malformed_input_gets_one_line_and_the_batch_goes_on(tmp_path, road_frames, capsys):
    good = tmp_path / "good.png"
    cv2.imwrite(str(good), road_frames[0].image)
    (tmp_path / "junk.png").write_bytes(b"this is not a png")
    (tmp_path / "empty").mkdir()
    cv2.imwrite(str(tmp_path / "one.png"), np.zeros((1, 1, 3), np.uint8))
    cv2.imwrite(str(tmp_path / "gray.png"), cv2.cvtColor(road_frames[1].image, cv2.COLOR_BGR2GRAY))
    cv2.imwrite(str(tmp_path / "rgba.png"), cv2.cvtColor(road_frames[1].image, cv2.COLOR_BGR2BGRA))
    cv2.imwrite(str(tmp_path / "deep.png"), road_frames[2].image.astype(np.uint16) * 257)
    ok, buf = cv2.imencode(".jpg", road_frames[0].image)
    (tmp_path / "cut.jpg").write_bytes(buf.tobytes()[: len(buf) // 2])
    (tmp_path / "bad.mp4").write_bytes(b"\x00" * 1000)
    inputs = ["junk.png", "empty", "one.png", "gray.png", "rgba.png", "deep.png", "cut.jpg", "bad.mp4",
              "missing.png", "good.png"]
    code, stdout, err = _run([tmp_path / p for p in inputs] + ["--json", "-"], capsys)
    assert code == 1
    lines = [line for line in err.splitlines() if line.startswith("signlane infer:")]
    expected = {"junk.png": "not an image", "empty": "no images or videos", "one.png": "1x1",
                "cut.jpg": "truncated JPEG", "bad.mp4": "cannot open video", "missing.png": "no such file"}
    for name, words in expected.items():
        hits = [line for line in lines if f"/{name}:" in line]
        assert len(hits) == 1 and words in hits[0], (name, hits)
    assert len(lines) == len(expected)
    # grayscale, RGBA, 16-bit and the good image all ran
    done = {json.loads(line)["source"].split("/")[-1] for line in stdout.splitlines()}
    assert done == {"gray.png", "rgba.png", "deep.png", "good.png"}


def test_save_masks_needs_out(tmp_path, capsys):
    code, _, err = _run([tmp_path, "--save-masks"], capsys)
    assert code == 2 and "--out" in err


def test_unknown_lane_method_is_one_clear_error(tmp_path, road_frames, capsys):
    p = tmp_path / "a.png"
    cv2.imwrite(str(p), road_frames[0].image)
    code, _, err = _run([p, "--lanes", "magic"], capsys)
    assert code == 2 and "unknown lane method 'magic'" in err


def test_a_video_is_driven_by_the_drive_stack_and_slows_for_a_stop_sign(tmp_path, capsys):
    """A recorded approach to a stop sign: infer plays it through the closed-loop stack (signs
    placed by odometry, the behaviour's stop), so the commands slow down once the sign is seen;
    frame by frame (--open-loop) the same video only cruises."""
    video = tmp_path / "stop.mp4"
    drive = DriveSampler(0, SamplerConfig(effects="clean", randomise=False, style="via"), track=track_with_stop_sign())
    with VideoOut(video, 20, (320, 240)) as out:
        for i in range(70):  # 8 m/s from 5 m to 33 m along the route: the sign stands at 30 m
            out.write(drive.sample(i).image)
    runs, summaries = {}, {}
    for mode in ("drive", "open"):
        js = tmp_path / f"{mode}.jsonl"
        code, _, summaries[mode] = _run([video, "--json", js, *(["--open-loop"] if mode == "open" else [])], capsys)
        assert code == 0, summaries[mode]
        runs[mode] = [json.loads(line) for line in js.read_text().splitlines()]
        assert len(runs[mode]) == 70 and all(r["lane"]["found"] for r in runs[mode])
    assert "state: stopping" in summaries["drive"] and "state: stopping" not in summaries["open"]
    drive_recs = runs["drive"]
    seen = min(r["frame"] for r in drive_recs if any(s["label"] == "stop" for s in r["signs"]))
    slowing = [r for r in drive_recs if r["control"]["state"] in ("approach", "stopping", "stopped")]
    assert len(slowing) >= 20 and min(r["frame"] for r in slowing) >= seen
    cruise = np.median([r["control"]["throttle"] for r in drive_recs[:seen]])
    assert drive_recs[-1]["control"]["throttle"] < 0.6 * cruise  # coasting down to the stop line
    assert {r["control"]["state"] for r in runs["open"]} == {"cruise"}
