"""Shared scenes and a runner for the lane-method tests."""
import json

import numpy as np
from importlib import resources

from signlane import lanes
from signlane.camera import Camera
from signlane.types import LaneEstimate
from signlane.world.render import Renderer
from signlane.world.route import Route
from signlane.world.scene import build_scene
from signlane.world.track import Track
from signlane.world.sampling import FrameSampler, SamplerConfig

LOOP = json.loads(resources.files("signlane.world").joinpath("maps/loop_demo.json").read_text())
STRAIGHTS = (5.0, 65.0, 125.0, 185.0)  # arc lengths on straight stretches of the demo loop
CAM = Camera()


def loop_scene() -> tuple[Route, Renderer]:
    track = Track.from_via(LOOP)
    return Route.loop(track), Renderer(build_scene(track, seed=3))


def run_method(method: str, image, camera=CAM, variant: str = "robust") -> LaneEstimate:
    return lanes.get(method, camera=camera, variant=variant)(image)


CLEAN = SamplerConfig(effects="clean", randomise=False)


def clean_samples(n: int = 12):
    smp = FrameSampler(7, CLEAN)
    return [smp.sample(i) for i in range(n)]


def find_stretch(route, pred, length_m: float) -> float:
    """First arc length s whose next length_m of route satisfies pred(curvature array)."""
    for s in np.arange(5.0, route.length - 60.0, 1.0):
        window = (route.s >= s) & (route.s <= s + length_m)
        if pred(route.curvature[window]):
            return float(s)
    raise AssertionError("route has no such stretch")


def drive_stretches(drive) -> dict[str, float]:
    """Where a clean drive's route is straight, bends right, bends left."""
    r = drive.route
    return {"straight": find_stretch(r, lambda k: np.all(np.abs(k) < 1e-4), 25.0),
            "right": find_stretch(r, lambda k: np.all(k > 0.015), 12.0),
            "left": find_stretch(r, lambda k: np.all(k < -0.015), 12.0)}
