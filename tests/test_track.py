"""Track model: VIA map loading, connectivity errors, procedural maps, routes."""
import copy
import json
import math
from importlib import resources

import numpy as np
import pytest

from signlane.world.procedural import generate_map
from signlane.world.route import Route, random_policy
from signlane.world.track import MapError, Track

LOOP = json.loads(resources.files("signlane.world").joinpath("maps/loop_demo.json").read_text())

# a hand-written 4x4 loop of four quarter turns (2x2 each), in VIA's format
RING = {"map_name": "ring", "bg_id": 0, "map_size": {"x": 4, "y": 4},
        "cell_datas": [{"id_inmap": 5, "tile_id": 2, "rot": 0}, {"id_inmap": 6, "tile_id": 2, "rot": 90},
                       {"id_inmap": 10, "tile_id": 2, "rot": 180}, {"id_inmap": 9, "tile_id": 2, "rot": 270}],
        "anchor_offset": {"x": 0.0, "y": 0.0}, "car_pos": {"x": 1.0, "y": 0.0}, "sign_obj_datas": [],
        "texture": "ignored"}


def test_ring_of_four_turns_is_a_circle():
    track = Track.from_via(RING, cell_m=10.0)
    lap = Route.loop(track)
    assert lap.closed
    # four quarter arcs of radius 1.5 cells around the centre of the 4x4 block
    r = np.hypot(*(lap.centre - lap.centre.mean(axis=0)).T)
    assert np.allclose(r, 15.0, atol=0.05)
    assert lap.length == pytest.approx(2 * math.pi * 15.0, rel=1e-3)
    # driving the default way round, the curvature sign is constant and |k| = 1/15
    k = np.median(lap.curvature)
    assert abs(abs(k) - 1 / 15.0) < 1e-3


def test_loop_demo_map_loads_with_signs_and_laps():
    track = Track.from_via(LOOP)
    assert len(track.tiles) == len(LOOP["cell_datas"])
    assert sorted(s.kind for s in track.signs) == ["left", "no_left", "right", "stop", "straight"]
    lap = Route.loop(track)
    assert lap.closed and 200 < lap.length < 400
    # the centreline is continuous: no gap between consecutive samples above the sample step
    steps = np.hypot(*np.diff(lap.centre, axis=0).T)
    assert steps.max() < 0.5


def test_map_frame_orientation():
    """Columns grow east (+x) and rows grow south (-y) in world metres."""
    track = Track.from_via(LOOP, cell_m=10.0)
    a = track.map_to_world(np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]))
    assert a[1, 0] > a[0, 0] and a[2, 1] < a[0, 1]


def test_broken_map_names_the_first_cell_that_does_not_connect():
    broken = copy.deepcopy(LOOP)
    # remove the straight at column 5, row 0 (id 5): the T-junction east of it now leads nowhere
    broken["cell_datas"] = [c for c in broken["cell_datas"] if c["id_inmap"] != 5]
    with pytest.raises(MapError) as e:
        Track.from_via(broken, source="broken.json")
    msg = str(e.value)
    assert "broken.json" in msg and "(col 4, row 0)" in msg and "east" in msg and "(col 5, row 0)" in msg
    assert "\n" not in msg


def test_rotated_straight_that_does_not_meet_its_neighbours_is_reported():
    broken = copy.deepcopy(LOOP)
    for c in broken["cell_datas"]:
        if c["id_inmap"] == 2:  # the straight at (2, 0) runs east-west; turn it north-south
            c["rot"] = 0
    with pytest.raises(MapError, match=r"cell \(col 2, row 0\).*leaves north .* which has no road"):
        Track.from_via(broken)


@pytest.mark.parametrize("bad,match", [({"map_size": {"x": 4}}, "not a VIA map"),
                                       ({"cell_datas": [{"id_inmap": 0, "tile_id": 9, "rot": 0}]}, "tile_id 9"),
                                       ({"cell_datas": [{"id_inmap": 0, "tile_id": 0, "rot": 45}]}, "rot 45"),
                                       ({"cell_datas": []}, "no road cells")])
def test_malformed_maps_give_one_clear_error(bad, match):
    data = {**copy.deepcopy(RING), **bad}
    with pytest.raises(MapError, match=match):
        Track.from_via(data)


def test_load_reports_unreadable_and_invalid_json(tmp_path):
    with pytest.raises(MapError, match="cannot read"):
        Track.load(tmp_path / "missing.json")
    bad = tmp_path / "bad.json"
    bad.write_text("{nope")
    with pytest.raises(MapError, match="not valid JSON"):
        Track.load(bad)


@pytest.mark.parametrize("seed", range(20))
def test_procedural_maps_connect_and_lap(seed):
    data = generate_map(seed)
    track = Track.from_via(data)  # connectivity is checked on load
    lap = Route.loop(track)
    assert lap.closed and lap.length > 100
    # sharpest bend on the lap: junction turns of half a cell (6 m) at 12 m cells
    assert np.abs(lap.curvature).max() < 1 / 5.5
    # a random walk through the junctions keeps going as long as asked
    walk = Route.drive(track, 1500.0, random_policy(np.random.default_rng(seed)))
    assert walk.length >= 1500.0


def test_procedural_maps_are_deterministic_and_varied():
    assert generate_map(5) == generate_map(5)
    kinds = set()
    for seed in range(30):
        kinds |= {c["tile_id"] for c in generate_map(seed)["cell_datas"]}
    assert kinds == {0, 1, 2, 3, 4, 5}  # every VIA tile type appears


def test_signs_face_the_traffic_they_are_for():
    track = Track.from_via(LOOP)
    stop = next(s for s in track.signs if s.kind == "stop")
    # the stop sign is for eastbound traffic on the top road: it faces west
    assert math.cos(stop.facing) < -0.99
    tee = track.tile_at((4, 0))
    west, south, east = (next(p for p in tee.ports if p.side == s) for s in "WSE")
    assert track.turn_of(west, south) == "right"  # eastbound, turning south
    assert track.turn_of(east, south) == "left"  # westbound, turning south
    assert track.turn_of(west, east) == "straight"


def test_procedural_maps_do_not_depend_on_the_process_hash_seed():
    """String hashing differs per process; maps must not (datasets are built by worker processes)."""
    import subprocess
    import sys
    code = ("import json; from signlane.world.procedural import generate_map; "
            "print(json.dumps([generate_map(s) for s in range(12)]))")
    outs = {subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                           env={**__import__("os").environ, "PYTHONHASHSEED": str(h)}).stdout for h in (1, 2, 3)}
    assert len(outs) == 1
