"""Pilot inference speed on one thread, beside the teacher's lane stage measured in the same run.

Frames are the simulator's own (640x480, both road styles); each is handed over as the drive
stack hands it: the 320-wide lane copy. "pilot" is the pilot's whole step (resize, HSV, the
net, reading the desire's branch); "net only" the onnxruntime call on a ready input; "teacher
lanes" the configured lane method on the same copy (the drive stack's `lanes` stage). Medians
over --repeats passes of all frames, after a warm-up pass.

    python benchmarks/pilot.py --model signlane/models/pilot.onnx [--model runs/pilotnet/pilot.onnx]
                               [--frames 40] [--repeats 5]
"""
from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")


def frames(n: int):
    """n frames per style from a short teacher drive on seed 0, as BGR 640x480."""
    from signlane.config import Config
    from signlane.sim.driver import Driver
    from signlane.sim.protocol import decode_telemetry
    from signlane.sim.simulator import SimConfig, Simulator
    from signlane.world.maps import load_track
    out = []
    for style in ("via", "painted"):
        sim = Simulator(load_track("random", style, 0), SimConfig())
        with Driver(Config()) as d:
            for i in range(n * 5):
                tel = decode_telemetry(sim.observe(send_time=False))
                _, cmd = d.step(tel, now=sim.t)
                sim.advance((cmd.steering, cmd.throttle))
                if i % 5 == 0:
                    out.append(tel.image_bgr)
    return out


def median_ms(fn, items, repeats: int) -> tuple[float, float]:
    """(median, 90th percentile) ms per item over repeats x items calls, after one warm-up pass."""
    import numpy as np
    for it in items:
        fn(it)
    times = []
    for _ in range(repeats):
        for it in items:
            t0 = time.perf_counter()
            fn(it)
            times.append((time.perf_counter() - t0) * 1e3)
    return float(np.median(times)), float(np.percentile(times, 90))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--model", type=Path, action="append", required=True, help="pilot ONNX file (repeatable)")
    ap.add_argument("--frames", type=int, default=40, help="frames per road style (default 40)")
    ap.add_argument("--repeats", type=int, default=5)
    a = ap.parse_args()
    import cv2
    cv2.setNumThreads(1)
    from signlane.config import Config
    from signlane.drive.perception import PerceptionStack
    from signlane.pilot import PilotModel, preprocess_frames
    from signlane.tables import table
    imgs = frames(a.frames)
    small = [cv2.resize(f, (320, 240), interpolation=cv2.INTER_AREA) for f in imgs]
    ps = PerceptionStack(Config.load(None, ["signs.enabled=false"]), lanes_width=0, junctions=False)
    lanes_ms, lanes_p90 = median_ms(ps.lanes_on, small, a.repeats)
    rows = [["teacher lanes (" + Config().lanes.method + ")", f"{lanes_ms:.3f}", f"{lanes_p90:.3f}", "-", "1.00"]]
    for path in a.model:
        m = PilotModel(path, threads=1)
        ms, p90 = median_ms(lambda f: m.step(f, "straight"), small, a.repeats)
        ready = [preprocess_frames([f], m.spec) for f in small]
        net, _ = median_ms(m.model.run, ready, a.repeats)
        rows.append([f"{path.stem} ({m.model.meta.get('arch', '?')}, {m.spec.width}x{m.spec.height})",
                     f"{ms:.3f}", f"{p90:.3f}", f"{net:.3f}", f"{ms / lanes_ms:.2f}"])
    print(f"{len(small)} frames (320x240 lane copies of 640x480 simulator frames), one thread, "
          f"median of {a.repeats} passes\n")
    print(table(["stage", "ms/frame median", "p90", "net only ms", "x teacher lanes"], rows))


if __name__ == "__main__":
    main()
