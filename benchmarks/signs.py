"""Sign classifier speed: per-crop latency at batch 1 and 16 on one thread (median over repeats),
against the proposal stage on the same frames as the baseline; with --recipe, also the wall time
of the whole reproduction recipe (generate, train, export) on this machine.

    python benchmarks/signs.py --model signs.onnx [--repeats 7]
    python benchmarks/signs.py --model signs.onnx --recipe --n 12000 --epochs 14   # minutes
"""
from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import cv2

from signlane.signs.classifier import DEFAULT_MODEL, SignClassifier, crop
from signlane.signs.proposals import propose
from signlane.world.sampling import FrameSampler, SamplerConfig


def median_ms(fn, repeats: int) -> float:
    runs = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        runs.append((time.perf_counter() - t0) * 1e3)
    return statistics.median(runs)


def recipe(n: int, epochs: int) -> dict[str, float]:
    """Run the README's recipe in a temp folder; seconds per step."""
    exe = [sys.executable, "-m", "signlane.cli"]
    with tempfile.TemporaryDirectory() as d:
        steps = {"generate": [*exe, "gen", "signs", "--n", str(n), "--out", f"{d}/data", "--seed", "1", "--workers", "2"],
                 "train": [*exe, "train", "signs", f"{d}/data", "--out", f"{d}/run", "--epochs", str(epochs)],
                 "export": [*exe, "export", "signs", f"{d}/run/checkpoints/best.ckpt", "--out", f"{d}/s.onnx"]}
        times = {}
        for name, cmd in steps.items():
            t0 = time.perf_counter()
            subprocess.run(cmd, check=True, capture_output=True)
            times[name] = time.perf_counter() - t0
    return times


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--model", type=Path, default=DEFAULT_MODEL)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--recipe", action="store_true", help="also time generate + train + export")
    ap.add_argument("--n", type=int, default=12000)
    ap.add_argument("--epochs", type=int, default=14)
    args = ap.parse_args()
    cv2.setNumThreads(1)
    clf = SignClassifier(args.model, threads=1, batch=16)
    sampler = FrameSampler(3, SamplerConfig(width=640, height=480, focus="signs"))
    frames = [sampler.sample(i).image for i in range(16)]
    crops = [crop(f, p.box) for f in frames for p in propose(f)] or [frames[0][:32, :32]]
    crops = (crops * 16)[:16]
    one = median_ms(lambda: [clf.probabilities([c]) for c in crops], args.repeats) / len(crops)
    sixteen = median_ms(lambda: clf.probabilities(crops), args.repeats) / len(crops)
    base = median_ms(lambda: [propose(f) for f in frames], args.repeats) / len(frames)
    print(f"{'what':<34} {'ms':>8} {'x proposals/frame':>18}")
    print(f"{'proposals, per 640x480 frame':<34} {base:8.3f} {1.0:18.2f}")
    print(f"{'classifier per crop, batch 1':<34} {one:8.3f} {one / base:18.2f}")
    print(f"{'classifier per crop, batch 16':<34} {sixteen:8.3f} {sixteen / base:18.2f}")
    if args.recipe:
        t = recipe(args.n, args.epochs)
        for k, v in t.items():
            print(f"{'recipe: ' + k:<34} {v:8.1f} s")
        print(f"{'recipe: total':<34} {sum(t.values()) / 60:8.1f} min (target <= 10)")


if __name__ == "__main__":
    main()
