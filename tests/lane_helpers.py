"""Shared scenes and a runner for the lane-method tests."""
import numpy as np

from signlane import lanes
from signlane.camera import Camera
from signlane.types import LaneEstimate
from signlane.world.render import Renderer
from signlane.world.route import Route
from signlane.world.scene import build_scene
from signlane.world.track import RoadStyle, Track
from signlane.world.sampling import FrameSampler, SamplerConfig

CAM = Camera()


def stadium(n: int = 8) -> dict:
    """A VIA map of a rectangle on an (n+4)-cell square grid: n-2 straights a side between four
    2x2 quarter turns, the car starting northbound on the west side's first straight."""
    W = H = n + 4
    cells = [(1, 1, 2, 180), (W - 2, 1, 2, 270), (W - 2, H - 2, 2, 0), (1, H - 2, 2, 90)]
    cells += [(c, r, 0, 90) for c in range(3, W - 3) for r in (1, H - 2)]
    cells += [(c, r, 0, 0) for r in range(3, H - 3) for c in (1, W - 2)]
    return {"map_name": "stadium", "map_size": {"x": W, "y": H}, "car_pos": {"x": 1, "y": 3},
            "cell_datas": [{"id_inmap": r * W + c, "tile_id": t, "rot": rot} for c, r, t, rot in cells]}


# arc lengths with 40 m or more of straight road ahead on the painted stadium (12 m cells: 72 m
# straights joined by quarter turns of 18 m radius)
STRAIGHTS = (5.0, 105.0, 205.0, 305.0)


def loop_scene(style: RoadStyle | None = None) -> tuple[Route, Renderer]:
    """Long straights in the painted two-lane style (these methods look for lane paint)."""
    track = Track.from_via(stadium(), style=style or RoadStyle())
    return Route.loop(track), Renderer(build_scene(track, seed=2))


# the road the Donkey-car autopilot (color-hough's published variant) was written for: a solid
# yellow line on the lane's left, a white one on its right
DONKEY_STYLE = RoadStyle(centre_line="solid", centre_color="yellow")


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
