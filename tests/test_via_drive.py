"""The drive server fed exactly what VIA sends: binary frames of UTF-8 JSON with N4 strings, speed
in miles per hour, the applied pedal, no extra keys, and the replies read the way VIA reads them.
The car must speed up, steer back towards the middle of VIA's kerbed road and stop at a stop sign."""
import json
import math
import re
import time

import numpy as np
from websockets.sync.client import connect

from signlane.config import Config
from signlane.sim.protocol import TELEMETRY_KEYS, decode_command
from signlane.sim.server import DriveServer, ServerOptions
from signlane.sim.simulator import SimConfig, Simulator
from signlane.world.route import Pose
from signlane.world.track import Track

N4 = re.compile(r"^-?\d{1,3}(,\d{3})*\.\d{4}$")


def straight_with_a_stop(rows: int = 16, stop_row: int = 10) -> dict:
    """A VIA map: a loop of 2x2 turns with a long north-south straight, and a stop sign for
    northbound traffic beside it at row stop_row (VIA's conventions: pos in cells, rot 0 faces
    south, so a sign read by a car driving north)."""
    W, H = 6, rows + 4
    cells = [(1, 1, 2, 180), (W - 2, 1, 2, 270), (W - 2, H - 2, 2, 0), (1, H - 2, 2, 90)]
    cells += [(c, r, 0, 90) for c in range(3, W - 3) for r in (1, H - 2)]
    cells += [(c, r, 0, 0) for r in range(3, H - 3) for c in (1, W - 2)]
    sign_x = (1 - W / 2) + (2.0 + 0.18 + 2.0) / 4  # 2 m beside the asphalt, right of northbound traffic
    return {"map_name": "straight_with_a_stop", "bg_id": 0, "map_size": {"x": W, "y": H},
            "car_pos": {"x": 1, "y": 3},
            "cell_datas": [{"id_inmap": r * W + c, "tile_id": t, "rot": rot} for c, r, t, rot in cells],
            "sign_obj_datas": [{"sign_id": 4, "pos": {"x": sign_x, "y": stop_row - H / 2}, "rot": 0.0}]}


def test_vias_own_frames_drive_the_car_off_centre_start_and_stop():
    track = Track.from_via(straight_with_a_stop())
    # VIA's bytes carry no clock, so the driver times itself by the wall clock: the simulation is
    # paced to it (at 15 frames/s, which a loaded machine keeps up with), as VIA runs in real time
    sim = Simulator(track, SimConfig(max_seconds=22.0, fps=15.0))
    p = sim.vehicle.pose  # start 0.8 m right of the middle of the 4 m carriageway
    sim.vehicle.pose = Pose(p.x + 0.8 * math.sin(p.heading), p.y - 0.8 * math.cos(p.heading), p.heading)
    log = []
    with DriveServer(Config(), ServerOptions(port=0, sync_signs=True)) as srv, connect(srv.url, max_size=None) as ws:
        start = time.monotonic()
        while not sim.done:
            time.sleep(max(0.0, sim.t - (time.monotonic() - start)))  # never ahead of the wall clock
            msg = sim.observe()  # VIA's bytes: no "time" key, the simulated clock is not on the wire
            if not log:
                assert isinstance(msg, bytes)
                tel = json.loads(msg.decode("utf-8"))
                assert tuple(tel) == TELEMETRY_KEYS and b" " not in msg
                assert all(N4.match(tel[k]) for k in TELEMETRY_KEYS[:3])
            ws.send(msg)  # bytes: a binary frame, as VIA sends
            steering, throttle = decode_command(ws.recv())  # read as VIA reads it
            sim.advance((steering, throttle))
            log.append((sim.t, steering, sim.vehicle.speed, sim.vehicle.pedal))
    t, steer, speed, pedal = (np.array(c) for c in zip(*log))
    assert np.median(steer[(t > 0.3) & (t < 1.5)]) < -0.02  # right of the middle: steer left
    assert speed.max() > 2.0 and set(np.unique(pedal)) <= {0.0, 0.5}  # it sped up, at VIA's half pedal
    stopped = t[(speed < 0.05) & (t > 3.0)]
    assert len(stopped) and stopped.max() - stopped.min() >= 2.0  # a full stop, held
    rep = sim.report()
    assert rep["stops"] == {"required": 1, "complied": 1}  # within 12 m before the sign
    assert rep["offroad_events"] == 0
