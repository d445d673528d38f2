"""Sign classifier speed: per-crop latency at batch 1 and 16 on one thread (median over repeats),
against the proposal stage on the same frames as the baseline, and the time from scratch to the
shipped quality (generate, train, export). Without --recipe that time is the one the model card
records; with --recipe the card's own commands run again in a temp folder (minutes) and the
model they make is scored on the card's test set, so the time comes with the quality it bought.

    python benchmarks/signs.py [--model signs.onnx] [--repeats 7]
    python benchmarks/signs.py --recipe        # re-runs signlane/models/signs.json's recipe
"""
from __future__ import annotations

import argparse
import json
import shlex
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
from signlane.tables import pairs, table

CARD = DEFAULT_MODEL.with_suffix(".json")
# step -> card section with its command (a card without a quantization section skips that step)
STEPS = {"generate": "data", "train": "training", "export": "export", "quantize": "quantization"}
# the card's output paths, moved into the temp folder (the recipe never writes the shipped files;
# its model is the file its `signlane ship` step names)
MOVED = ("data/signs", "runs/signs_int8", "runs/signs")


def median_ms(fn, repeats: int) -> float:
    runs = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        runs.append((time.perf_counter() - t0) * 1e3)
    return statistics.median(runs)


def relocate(command: str, tmp: Path) -> list[str]:
    """A card command as argv running the package's CLI, its output paths moved under tmp."""
    argv = shlex.split(command)
    if argv[0] != "signlane":
        raise ValueError(f"card command does not start with 'signlane': {command}")
    out = [sys.executable, "-m", "signlane.cli"]
    for arg in argv[1:]:
        for path in MOVED:
            if arg == path or arg.startswith(path + "/"):
                arg = str(moved(path, tmp)) + arg[len(path):]
        out.append(arg)
    return out


def moved(path: str, tmp: Path) -> Path:
    """Where one of MOVED lands under tmp (flattened, so data/signs and runs/signs stay apart)."""
    return tmp / path.replace("/", "_")


def recipe(card: dict) -> tuple[dict[str, float], dict]:
    """Run the card's recipe in a temp folder; seconds per step and the new model's test scores."""
    from signlane.evaluate import eval_signs
    with tempfile.TemporaryDirectory() as d:
        times = {}
        for step, section in STEPS.items():
            if section not in card:
                continue
            t0 = time.perf_counter()
            subprocess.run(relocate(card[section]["command"], Path(d)), check=True, capture_output=True)
            times[step] = time.perf_counter() - t0
        return times, eval_signs(test_set(card), Path(relocate(card["ship"]["command"], Path(d))[4]))


def test_set(card: dict) -> Path:
    """The card's test set folder, generated (untimed) by its own command when missing."""
    generate, _ = card["evaluate"].split("&&")
    argv = shlex.split(generate)
    path = Path(argv[argv.index("--out") + 1])
    if not (path / "manifest.json").exists():
        subprocess.run(relocate(generate, Path(".")), check=True, capture_output=True)
    return path


def latency_rows(model: Path, repeats: int) -> list[tuple[str, float]]:
    cv2.setNumThreads(1)
    clf = SignClassifier(model, threads=1, batch=16)
    sampler = FrameSampler(3, SamplerConfig(width=640, height=480, focus="signs"))
    frames = [sampler.sample(i).image for i in range(16)]
    crops = [crop(f, p.box) for f in frames for p in propose(f)] or [frames[0][:32, :32]]
    crops = (crops * 16)[:16]
    one = median_ms(lambda: [clf.probabilities([c]) for c in crops], repeats) / len(crops)
    sixteen = median_ms(lambda: clf.probabilities(crops), repeats) / len(crops)
    base = median_ms(lambda: [propose(f) for f in frames], repeats) / len(frames)
    return [("proposals, per 640x480 frame", base), ("classifier per crop, batch 1", one),
            ("classifier per crop, batch 16", sixteen)]


def print_recipe(source: str, times: dict[str, float], scores: dict) -> None:
    print(f"\nrecipe ({source})")
    print(pairs([(k, f"{v:.1f} s") for k, v in times.items()]
                + [("total", f"{sum(times.values()) / 60:.1f} min (target <= 10)"),
                   ("its model on the test set", f"accuracy {scores['test_accuracy']:.4f}, min recall "
                    f"{scores['test_min_recall']:.4f}, non-signs accepted {scores['test_non_sign_accepted']:.4f}")]))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--model", type=Path, default=DEFAULT_MODEL)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--recipe", action="store_true", help="re-run the model card's recipe and time it (minutes)")
    args = ap.parse_args()
    rows = latency_rows(args.model, args.repeats)
    base = rows[0][1]
    print(table(["what (1 thread)", "ms", "x proposals/frame"], [[name, f"{ms:.3f}", f"{ms / base:.2f}"] for name, ms in rows]))
    card = json.loads(CARD.read_text())
    if args.recipe:
        times, s = recipe(card)
        scores = {"test_accuracy": s["accuracy"], "test_min_recall": s["min_recall"],
                  "test_non_sign_accepted": s["non_sign_accepted"]}
        print_recipe("measured now", times, scores)
    else:
        times = {k: v for k, v in card["time_s"].items() if k != "total"}
        print_recipe("model card", times, card["metrics"])


if __name__ == "__main__":
    main()
