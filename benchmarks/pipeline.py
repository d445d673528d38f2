"""The whole frame -> command path, per stage, one thread, side by side with the VIA tutorial's.

One table, medians over repeats, the same frames in the same run:
  (a) S1 as published, rebuilt from our own parts: `canny-scan` published on the full frame,
      `published` colour-mask proposals, a LeNet-sized classifier at 32x32 (the tutorial's
      design: conv 6 5x5, pool, conv 16 5x5, pool, dense 120-84-n, run with onnxruntime; its
      weights are untrained, which costs the same) and S1's proportional steering;
  (b) signlane's default driver path, exactly as `signlane drive` runs it (`Driver.step`: the
      320-wide lane copy, `auto` lanes, junctions, sign proposals on the face rows (whole on one
      frame in five, around the last proposals between), the shipped sign classifier,
      confirmation, odometry, the behaviour state machine), with the signs in step with the frame;
  (c) every lane method alone, as the driver runs it (on the 320-wide copy).
Columns per stage (ms per frame): decode (a VIA message: JSON, base64, JPEG; for (a) as the
tutorial does it, json + base64 + cv2.imdecode, for ours `decode_telemetry` with its checks),
lanes, junction, proposals, classifier, control; then total, total / (a) total, and the same
without decode ("path": frame -> command, what the issue's 4 ms target counts) and its ratio, and
"after": the work the driver puts off until the command is out (`answered()`), which runs in the
gap before the next frame and is in no column before it. Frames: consecutive 640x480 VIA
frames (JPEG quality 75) of drives in both render styles, plus, per folder given, its images
scaled to 640x480.

    python benchmarks/pipeline.py [--frames 60] [--repeats 5] [FOLDER ...]
"""
from __future__ import annotations

import argparse
import base64
import json
import statistics
import tempfile
import time
import warnings
from pathlib import Path

import cv2
import numpy as np

from signlane import lanes
from signlane.camera import via_camera
from signlane.config import Config
from signlane.control import S1Proportional
from signlane.media import IMAGE_EXT
from signlane.signs.proposals import ProposalParams, propose
from signlane.sim.driver import Driver
from signlane.sim.protocol import decode_telemetry, encode_jpeg, encode_telemetry
from signlane.tables import table
from signlane.world.sampling import DriveSampler, SamplerConfig

STAGES = ["decode", "lanes", "junction", "proposals", "classifier", "control"]


def rendered_messages(style: str, n: int, seed: int) -> list[bytes]:
    """VIA messages of n consecutive frames of a drive in one style, seen by VIA's camera (the
    simulator's in both styles, and the one the drivers below are configured for)."""
    sampler = DriveSampler(seed, SamplerConfig(width=640, height=480, style=style, effects="normal"), fps=30.0,
                           camera=via_camera(640, 480))
    return [encode_telemetry(0.0, 0.5, 5.0, encode_jpeg(sampler.sample(i).image)) for i in range(n)]


def folder_messages(folder: Path, n: int) -> list[bytes]:
    files = sorted(p for p in folder.rglob("*") if p.suffix.lower() in IMAGE_EXT)[:n]
    out = []
    for f in files:
        img = cv2.imread(str(f))
        if img is not None:
            out.append(encode_telemetry(0.0, 0.5, 5.0, encode_jpeg(cv2.resize(img, (640, 480), interpolation=cv2.INTER_AREA))))
    return out


class LeNet32:
    """The tutorial's classifier design at 32x32, exported to ONNX and run by onnxruntime."""

    def __init__(self, n_classes: int = 7):
        import onnxruntime as ort
        import torch
        from torch import nn
        torch.manual_seed(0)
        net = nn.Sequential(nn.Conv2d(3, 6, 5), nn.ReLU(), nn.MaxPool2d(2), nn.Conv2d(6, 16, 5), nn.ReLU(),
                            nn.MaxPool2d(2), nn.Flatten(), nn.Linear(16 * 5 * 5, 120), nn.ReLU(), nn.Linear(120, 84),
                            nn.ReLU(), nn.Linear(84, n_classes)).eval()
        with tempfile.TemporaryDirectory() as d, warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the exporter's notice about its newer path
            path = Path(d) / "lenet.onnx"
            torch.onnx.export(net, torch.zeros(1, 3, 32, 32), str(path), input_names=["x"], output_names=["y"],
                              dynamic_axes={"x": {0: "n"}, "y": {0: "n"}}, dynamo=False)
            opts = ort.SessionOptions()
            opts.intra_op_num_threads = opts.inter_op_num_threads = 1
            self.session = ort.InferenceSession(str(path), opts, providers=["CPUExecutionProvider"])

    def __call__(self, image: np.ndarray, boxes) -> np.ndarray:
        if not boxes:
            return np.zeros((0, 7), np.float32)
        crops = [cv2.resize(image[max(0, y):y + h, max(0, x):x + w], (32, 32)) for x, y, w, h in boxes]
        x = (np.stack(crops).astype(np.float32) / 255.0).transpose(0, 3, 1, 2)
        return self.session.run(None, {"x": x})[0]


def s1_pipeline(lenet: LeNet32):
    """(a): returns step(message) -> {stage: ms}."""
    cam = via_camera(640, 480)
    lane = lanes.get("canny-scan", camera=cam, variant="published")
    steer = S1Proportional(cam)
    params = ProposalParams.published()

    def step(message: bytes) -> dict[str, float]:
        t = [time.perf_counter()]
        msg = json.loads(message)  # the tutorial's decode: no checks
        img = cv2.imdecode(np.frombuffer(base64.b64decode(msg["image"]), np.uint8), cv2.IMREAD_COLOR)
        t.append(time.perf_counter())
        est = lane(img)
        t.append(time.perf_counter())
        t.append(t[-1])  # S1 has no junction stage
        found = propose(img, params)
        t.append(time.perf_counter())
        lenet(img, [d.box for d in found])
        t.append(time.perf_counter())
        steer.step(est)
        t.append(time.perf_counter())
        return {s: (b - a) * 1e3 for s, a, b in zip(STAGES, t[:-1], t[1:])}
    return step, lambda: (lane.reset(), steer.reset())


def driver_pipeline(config: Config):
    """(b) with the full config, (c) with signs off and one lane method."""
    driver = Driver(config, sync_signs=True)
    now = [0.0]

    def step(message: bytes) -> dict[str, float]:
        t0 = time.perf_counter()
        tel = decode_telemetry(message)
        t1 = time.perf_counter()
        now[0] += 1 / 30
        per, _ = driver.step(tel, now=now[0])
        t2 = time.perf_counter()
        driver.answered()  # the command is out: the work put off until then (auto's look for lane paint)
        after = (time.perf_counter() - t2) * 1e3
        ms = per.timing_ms
        out = {"decode": (t1 - t0) * 1e3, "lanes": ms.get("lanes", 0.0), "junction": ms.get("junction", 0.0),
               "proposals": ms.get("signs_proposals", 0.0), "classifier": ms.get("signs_classifier", 0.0)}
        # control: the behaviour step plus what the driver does around its stages (odometry, copies)
        out["control"] = max(0.0, (t2 - t1) * 1e3 - sum(out[k] for k in ("lanes", "junction")) - ms.get("signs", 0.0))
        out["after"] = after
        return out
    return step, driver.reset


def measure(pipeline, messages: list[bytes], repeats: int) -> dict[str, float]:
    """Per stage, the median over repeats of the mean ms per frame; one warm-up pass first."""
    step, reset = pipeline
    for m in messages[:5]:
        step(m)
    runs = []
    for _ in range(repeats):
        reset()
        acc = dict.fromkeys(STAGES + ["after"], 0.0)
        for m in messages:
            for k, v in step(m).items():
                acc[k] += v
        runs.append({k: v / len(messages) for k, v in acc.items()})
    out = {k: statistics.median(r[k] for r in runs) for k in STAGES + ["after"]}
    out["total"] = statistics.median(sum(r[k] for k in STAGES) for r in runs)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("folders", nargs="*", type=Path, help="folders of your own frames (scaled to 640x480)")
    ap.add_argument("--frames", type=int, default=60, help="frames per set (default 60)")
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    cv2.setNumThreads(1)
    sets = {f"{style} drive": rendered_messages(style, args.frames, 11) for style in ("via", "painted")}
    for folder in args.folders:
        sets[str(folder)] = folder_messages(folder, args.frames)
    lenet = LeNet32()
    rows = []
    for name, messages in sets.items():
        if not messages:
            print(f"{name}: no images")
            continue
        s1 = measure(s1_pipeline(lenet), messages, args.repeats)
        results = [("(a) S1 as published", s1), ("(b) default driver", measure(driver_pipeline(Config()), messages,
                                                                             args.repeats))]
        for method in lanes.available():
            cfg = Config.load(None, ["signs.enabled=false", f"lanes.method={method}"])
            results.append((f"(c) lanes: {method}", measure(driver_pipeline(cfg), messages, args.repeats)))
        s1_path = s1["total"] - s1["decode"]
        for label, r in results:
            path = r["total"] - r["decode"]
            rows.append([name, label] + [f"{r[k]:.2f}" for k in STAGES + ["total"]]
                        + [f"{r['total'] / s1['total']:.2f}", f"{path:.2f}", f"{path / s1_path:.2f}", f"{r['after']:.2f}"])
    print(f"ms per 640x480 frame, 1 thread, median of {args.repeats} repeats over {args.frames} consecutive frames")
    print(table(["frames", "pipeline"] + STAGES + ["total", "x S1", "path", "path x S1", "after"], rows))
    print("after: the work the driver puts off until the frame's command is out (DriveStack.answered(): auto's "
          "carriageway or paint method where the frames before chose the other, its drivable and debug masks, a "
          "painted road's junction detector, the sign band's whole-row check), not in the frame's path")


if __name__ == "__main__":
    main()
