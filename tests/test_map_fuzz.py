"""Property-based: whatever an editor-made map file holds, the loader gives a Track (what VIA would
still draw) or one MapError line, and the map's picture (`signlane map --png`) never raises.
Maps are VIA's own bundled town with random edits (tiles changed, removed or added, odd rotations,
junk values, signs anywhere), so most still load and the loader's tolerance is what is tested."""
import copy
import json
import math
from importlib import resources

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from signlane.world.scene import build_scene
from signlane.world.topdown import draw_topdown
from signlane.world.track import MapError, Track

FUZZ = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
BASE = json.loads(resources.files("signlane.world").joinpath("maps/via_town.json").read_text())

junk = st.one_of(st.none(), st.booleans(), st.text(max_size=4), st.floats(allow_nan=True, allow_infinity=True),
                 st.integers(min_value=-10 ** 12, max_value=10 ** 12))
cells = BASE["map_size"]["x"] * BASE["map_size"]["y"]
tile = st.fixed_dictionaries({"id_inmap": st.integers(-3, cells + 3), "tile_id": st.integers(-1, 8),
                              "rot": st.sampled_from([0, 90, 180, 270, 45, -90, 360, 720])})
edit = st.one_of(
    st.tuples(st.just("tile"), st.integers(0, 200), tile),  # replace a tile
    st.tuples(st.just("drop"), st.integers(0, 200), st.none()),  # remove one
    st.tuples(st.just("add"), st.integers(0, 200), tile),  # add one (perhaps overlapping)
    st.tuples(st.just("field"), st.integers(0, 200), st.tuples(st.sampled_from(["id_inmap", "tile_id", "rot"]), junk)),
    st.tuples(st.just("sign"), st.integers(0, 200), st.fixed_dictionaries(
        {"sign_id": st.integers(-1, 8), "pos": st.fixed_dictionaries({"x": st.floats(-1e6, 1e6), "y": st.floats(-1e6, 1e6)}),
         "rot": st.floats(-720, 720)})),
    st.tuples(st.just("top"), st.integers(0, 200), st.tuples(st.sampled_from(["car_pos", "bg_id", "map_size"]), junk)),
)


def _edited(edits) -> dict:
    data = copy.deepcopy(BASE)
    for kind, i, value in edits:
        cd, signs = data["cell_datas"], data["sign_obj_datas"]
        if kind == "tile" and cd:
            cd[i % len(cd)] = value
        elif kind == "drop" and cd:
            cd.pop(i % len(cd))
        elif kind == "add":
            cd.append(value)
        elif kind == "field" and cd:
            cd[i % len(cd)][value[0]] = value[1]
        elif kind == "sign" and signs:
            signs[i % len(signs)] = value
        elif kind == "top":
            data[value[0]] = value[1]
    return data


@FUZZ
@given(st.lists(edit, min_size=1, max_size=4))
def test_an_edited_map_loads_or_gives_one_map_error_line(edits):
    try:
        track = Track.from_via(_edited(edits))
    except MapError as e:
        assert str(e) and "\n" not in str(e)
        return
    assert track.tiles and all(math.isfinite(v) for s in track.signs for v in (s.x, s.y, s.facing))
    img = draw_topdown(build_scene(track))
    assert img.ndim == 3 and img.dtype == np.uint8 and img.size > 0


def test_most_edited_maps_still_load():
    """The property above is not vacuous: single tile edits of the town mostly load, as VIA
    would draw them (dead ends and unknown tiles are warnings)."""
    loaded = 0
    for i in range(0, 40):
        edits = [("tile", i * 7, {"id_inmap": BASE["cell_datas"][(i * 7) % len(BASE["cell_datas"])]["id_inmap"],
                                  "tile_id": i % 9, "rot": (90 * i) % 360})]
        try:
            Track.from_via(_edited(edits))
            loaded += 1
        except MapError:
            pass
    assert loaded >= 30
