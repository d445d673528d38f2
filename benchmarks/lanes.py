"""Lane-method speed: ms per frame at 320x240 and 640x480, one thread, median over repeats.

The baseline row is a bare cv2.Canny on the same frames (the cheapest step every classical
method pays), measured in the same run; 'x canny' says how many of those a method costs.
The learned `segnet` (when its model is present) gets two rows: `segnet:model` is the network
alone (onnxruntime on the preprocessed input, 1 thread) and `segnet:robust` the whole method.

    python benchmarks/lanes.py [--frames 60] [--repeats 5] [--method NAME ...]
"""
from __future__ import annotations

import argparse
import statistics
import time

import cv2

from signlane import lanes
from signlane.world.sampling import FrameSampler, SamplerConfig
from signlane.tables import table


def median_ms(fn, frames, repeats: int) -> float:
    runs = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for f in frames:
            fn(f)
        runs.append((time.perf_counter() - t0) / len(frames) * 1e3)
    return statistics.median(runs)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=60)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--method", action="append", help="method(s) to time (default: all available)")
    args = ap.parse_args()
    cv2.setNumThreads(1)
    methods = args.method or lanes.available()
    rows = []
    for w, h in ((320, 240), (640, 480)):
        sampler = FrameSampler(7, SamplerConfig(width=w, height=h, effects="normal"))
        samples = [sampler.sample(i) for i in range(args.frames)]
        frames = [s.image for s in samples]
        base = median_ms(lambda f: cv2.Canny(cv2.cvtColor(f, cv2.COLOR_BGR2GRAY), 150, 200), frames, args.repeats)
        rows.append((f"{w}x{h}", "cv2.Canny (baseline)", base, 1.0))
        for name in methods:
            if name == "segnet":
                rows += _segnet_rows(f"{w}x{h}", samples, base, args.repeats)
                continue
            for variant in ("robust", "published"):
                m = lanes.get(name, camera=samples[0].truth.nominal_camera, variant=variant)
                t = median_ms(lambda f: (m.reset(), m(f)), frames, args.repeats)
                rows.append((f"{w}x{h}", f"{name}:{variant}", t, t / base))
    print(table(["size", "method", "ms/frame", "x canny"],
                [[size, name, f"{ms:.2f}", f"{ratio:.1f}"] for size, name, ms, ratio in rows]))


def _segnet_rows(size: str, samples, base: float, repeats: int) -> list[tuple]:
    """Model-only and whole-method ms of segnet; none when no model is present."""
    from signlane.lanes import seg_model
    if not seg_model.DEFAULT_MODEL.exists():
        print(f"segnet skipped: no model at {seg_model.DEFAULT_MODEL}")
        return []
    model = seg_model.load(str(seg_model.DEFAULT_MODEL), 1)
    inputs = [seg_model.preprocess_frames([s.image], model.spec) for s in samples]
    t_model = median_ms(model.model.run, inputs, repeats)
    m = lanes.get("segnet", camera=samples[0].truth.nominal_camera)
    t = median_ms(lambda f: (m.reset(), m(f)), [s.image for s in samples], repeats)
    return [(size, "segnet:model", t_model, t_model / base), (size, "segnet:robust", t, t / base)]


if __name__ == "__main__":
    main()
