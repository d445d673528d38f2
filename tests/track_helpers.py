"""Track-building test helpers: a VIA map with a sign placed where a test needs it."""
import math

import numpy as np

from signlane.world.procedural import generate_map
from signlane.world.route import Route
from signlane.world.track import Track


def sign_ahead(track: Track, s_m: float, label_id: int) -> dict:
    """A VIA sign entry 3.4 m right of the ego lane s_m metres along the start route, facing the
    car: pos in cells from the grid centre (4 m cells), rot counter-clockwise from facing south."""
    route = Route.drive(track, s_m + 20)
    pose = route.pose_at(route.start_s + s_m)
    xy = (np.array([pose.x, pose.y]) + 3.4 * pose.right) / 4.0
    facing = pose.heading + math.pi
    return {"sign_id": label_id, "pos": {"x": float(xy[0]), "y": float(xy[1])},
            "rot": (math.degrees(facing) + 90.0) % 360}


def track_with_stop_sign(seed: int = 3, s_m: float = 30.0) -> Track:
    """A small procedural VIA-style track whose only sign is a stop sign s_m metres along the
    start route (sign id 4: stop)."""
    data = generate_map(seed, size="small", sign_prob=0.0)
    data["sign_obj_datas"] = [sign_ahead(Track.from_via(data), s_m, 4)]
    return Track.from_via(data)
