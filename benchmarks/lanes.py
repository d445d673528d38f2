"""Lane-method speed: ms per frame at 320x240 and 640x480, one thread, median over repeats.

The baseline row is a bare cv2.Canny on the same frames (the cheapest step every classical
method pays), measured in the same run; 'x canny' says how many of those a method costs.
The learned `segnet` (when its model is present) gets two rows: `segnet:model` is the network
alone (onnxruntime on the preprocessed input, 1 thread) and `segnet:robust` the whole method.
A road model (`--lanes-model FILE` with a drivable head, or the shipped one if it is one) adds
`auto+model` (auto on the model's road and paint), and at 640x480 the lane stage as the driver
runs it: `driver: auto` and `driver: auto+model` (the frame scaled to a 320-wide copy first,
drive.lanes_width, then the method on it; tracking state carried frame to frame, as in a drive).

    python benchmarks/lanes.py [--frames 60] [--repeats 5] [--method NAME ...] [--lanes-model FILE]
"""
from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

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
    ap.add_argument("--lanes-model", help="segnet's model and auto's road model (default: the shipped one)")
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
                rows += _segnet_rows(f"{w}x{h}", samples, base, args.repeats, args.lanes_model)
                continue
            for variant in ("robust", "published"):
                m = lanes.get(name, camera=samples[0].truth.nominal_camera, variant=variant)
                t = median_ms(lambda f: (m.reset(), m(f)), frames, args.repeats)
                rows.append((f"{w}x{h}", f"{name}:{variant}", t, t / base))
        road = _road_model(args.lanes_model)
        if road and (args.method is None or "auto" in args.method):
            m = lanes.get("auto", camera=samples[0].truth.nominal_camera, model=road)
            t = median_ms(lambda f: (m.reset(), m(f)), frames, args.repeats)
            rows.append((f"{w}x{h}", "auto+model", t, t / base))
        if w == 640 and (args.method is None or "auto" in args.method):
            rows += _driver_rows(samples, base, args.repeats, road)
    print(table(["size", "method", "ms/frame", "x canny"],
                [[size, name, f"{ms:.2f}", f"{ratio:.1f}"] for size, name, ms, ratio in rows]))


def _road_model(path: str | None) -> str | None:
    """The road model to time auto with: the given file or the shipped one, if it has a road head."""
    from signlane.lanes import seg_model
    f = seg_model.resolve(path or "")
    if not Path(f).exists() or not seg_model.load(f, 1).has_drivable:
        print(f"auto+model skipped: {f} is not a road model")
        return None
    return f


def _driver_rows(samples, base: float, repeats: int, road: str | None) -> list[tuple]:
    """The driver's lane stage on 640x480 frames: a 320-wide copy, then auto (with the road
    model), its state carried over the consecutive frames."""
    from signlane.config import DriveConfig
    lw = DriveConfig().lanes_width
    frames = [s.image for s in samples]
    h, w = frames[0].shape[:2]
    small = (lw, round(h * lw / w))
    cam = samples[0].truth.nominal_camera.with_size(*small)
    out = []
    for label, extra in (("driver: auto", {}), ("driver: auto+model", {"model": road})):
        if "model" in extra and not road:
            continue
        m = lanes.get("auto", camera=cam, **extra)
        t = median_ms(lambda f: m(cv2.resize(f, small, interpolation=cv2.INTER_AREA)), frames, repeats)
        out.append(("640x480", label, t, t / base))
    return out


def _segnet_rows(size: str, samples, base: float, repeats: int, path: str | None = None) -> list[tuple]:
    """Model-only and whole-method ms of segnet; none when no model is present."""
    from signlane.lanes import seg_model
    f = seg_model.resolve(path or "")
    if not Path(f).exists():
        print(f"segnet skipped: no model at {f}")
        return []
    model = seg_model.load(f, 1)
    inputs = [seg_model.preprocess_frames([s.image], model.spec) for s in samples]
    t_model = median_ms(model.model.run, inputs, repeats)
    m = lanes.get("segnet", camera=samples[0].truth.nominal_camera, model=f)
    t = median_ms(lambda f: (m.reset(), m(f)), [s.image for s in samples], repeats)
    return [(size, "segnet:model", t_model, t_model / base), (size, "segnet:robust", t, t / base)]


if __name__ == "__main__":
    main()
