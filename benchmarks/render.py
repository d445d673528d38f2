"""World renderer speed: frames/s per core at 320x240 and 640x480, with ground truth.

Prints a table of medians over repeats. The baseline row is the cost of a bare
cv2.warpPerspective of a full frame (the cheapest possible 'render'), measured in the same run,
so the ratio column says how many such warps one rendered frame costs.

    python benchmarks/render.py [--frames 200] [--repeats 5]
"""
from __future__ import annotations

import argparse
import statistics
import time

import cv2
import numpy as np

from signlane.camera import Camera
from signlane.world.effects import Effects
from signlane.world.procedural import generate_map
from signlane.world.render import Renderer
from signlane.world.route import Route
from signlane.world.scene import build_scene
from signlane.world.track import Track
from signlane.tables import table


def time_per_frame(fn, frames: int, repeats: int) -> float:
    runs = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for i in range(frames):
            fn(i)
        runs.append((time.perf_counter() - t0) / frames)
    return statistics.median(runs)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=200)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--seed", type=int, default=4)
    args = ap.parse_args()
    cv2.setNumThreads(1)  # per-core numbers
    track = Track.from_via(generate_map(args.seed))
    route = Route.loop(track)
    rows = []
    for w, h in ((320, 240), (640, 480)):
        cam = Camera(width=w, height=h)
        src = np.zeros((h, w, 3), np.uint8)
        hom = cam.ground_to_image_h()
        base = time_per_frame(lambda i: cv2.warpPerspective(src, hom, (w, h)), args.frames, args.repeats)
        for preset in ("clean", "normal", "hard"):
            scene = build_scene(track, seed=1, randomise=preset != "clean")
            renderer = Renderer(scene)
            effects = Effects.named(preset)
            rng = np.random.default_rng(0)
            step = route.length / args.frames
            renderer.render_on_route(route, 0.0, cam, effects=effects, rng=rng)  # warm caches
            t = time_per_frame(lambda i: renderer.render_on_route(route, i * step, cam, effects=effects, rng=rng),
                               args.frames, args.repeats)
            rows.append((f"{w}x{h}", preset, t * 1e3, 1.0 / t, t / base))
    print(table(["size", "effects", "ms/frame", "frames/s", "x warp"],
                [[size, preset, f"{ms:.2f}", f"{fps:.0f}", f"{ratio:.1f}"] for size, preset, ms, fps, ratio in rows]))
    print("targets: >= 300 frames/s at 320x240 and >= 80 at 640x480 (clean, one core)")


if __name__ == "__main__":
    main()
