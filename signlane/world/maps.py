"""Where a track comes from, for every command: a bundled map, a procedural seed, or a VIA map
file, drawn in a road style (VIA's own kerbed carriageway by default, or painted lanes)."""
from __future__ import annotations

import json
from importlib import resources
from pathlib import Path

from signlane.world.procedural import generate_map
from signlane.world.track import RoadStyle, Track

BUNDLED_MAPS = ("via_town", "loop_demo")
STYLES = ("via", "painted")


def bundled_map(name: str = "via_town", style: str = "via") -> Track:
    """A map shipped in signlane/world/maps (VIA's editor format)."""
    if name not in BUNDLED_MAPS:
        raise ValueError(f"no bundled map {name!r} (bundled: {', '.join(BUNDLED_MAPS)})")
    data = json.loads(resources.files("signlane.world").joinpath(f"maps/{name}.json").read_text())
    return Track.from_via(data, style=RoadStyle.named(style), source=name)


def load_track(spec: str | Path, style: str = "via", seed: int = 0, size: str = "medium") -> Track:
    """`spec`: a bundled map's name, "random" (the procedural map of `seed`), or a map file.
    Raises MapError (a bad file) or ValueError (an unknown style or name)."""
    road = RoadStyle.named(style)
    if str(spec) in BUNDLED_MAPS:
        return bundled_map(str(spec), style)
    if str(spec) == "random":
        # painted-road tracks have no dead ends: the painted-lane driver cannot see one coming
        # on cells three times VIA's (README, limitations)
        dead = {} if road.kind == "via" else {"dead_end_prob": 0.0}
        return Track.from_via(generate_map(seed, size=size, **dead), style=road, source=f"random seed {seed}")
    return Track.load(spec, style=road)
