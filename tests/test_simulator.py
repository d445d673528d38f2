"""The local simulator's transport and timing: VIA's bytes and binary frames, the image one frame
late, replies applied to the car as they arrive, lockstep's "time" key, frame rates."""
import argparse
import json
import threading
import time

import numpy as np
import pytest
from websockets.sync.server import serve

from signlane.commands.sim import fps_arg
from signlane.sim.protocol import TELEMETRY_KEYS, decode_telemetry, parse_number
from signlane.sim.simulator import SimConfig, Simulator, run_client, run_inprocess
from signlane.types import Command
from signlane.world.procedural import generate_map
from signlane.world.track import Track


@pytest.fixture(scope="module")
def track():
    return Track.from_via(generate_map(3, size="small"))


def small(**kw) -> SimConfig:
    return SimConfig(**{"width": 96, "height": 72, **kw})


def test_observe_sends_vias_bytes(track):
    sim = Simulator(track, small())
    msg = sim.observe()
    assert isinstance(msg, bytes) and msg.startswith(b'{"steering_angle":"0.0000","throttle":"0.0000",'
                                                     b'"speed":"0.0000","image":"/9j/')
    assert tuple(json.loads(msg)) == TELEMETRY_KEYS  # no "time": VIA sends none
    assert b'"time":"0.0000"}' in sim.observe(send_time=True)
    comma = Simulator(track, small(decimal=","))
    comma.advance((0.5, 1.0))
    comma.advance(None)
    assert b'"steering_angle":"12,5000","throttle":"0,5000"' in comma.observe()


def test_image_lags_the_numbers_by_one_frame(track):
    sim = Simulator(track, small())
    first = decode_telemetry(sim.observe())
    for _ in range(30):
        sim.advance((0.0, 1.0))
    late = decode_telemetry(sim.observe())  # this frame's numbers, the previous message's image
    now = decode_telemetry(sim.observe())  # the same pose again: this one carries `late`'s render
    assert late.speed_mps > 0.5 and late.speed_mps == now.speed_mps
    assert late.jpeg == first.jpeg and now.jpeg != late.jpeg
    sim2 = Simulator(track, small(image_lag_frames=0))
    sim2.observe()
    for _ in range(30):
        sim2.advance((0.0, 1.0))
    assert decode_telemetry(sim2.observe()).jpeg == now.jpeg  # no lag: the current frame's render


def test_no_new_reply_keeps_the_last_steering_and_pedal(track):
    sim = Simulator(track, small())
    sim.advance((0.5, 1.0))
    for _ in range(15):
        sim.advance(None)
    assert sim.vehicle.wheel_deg == 12.5 and sim.vehicle.pedal == 0.5 and sim.vehicle.speed > 0.1


def test_frame_rates(track):
    sim = Simulator(track, small(fps=60))
    for _ in range(60):
        sim.advance((0.0, 0.5))
    assert sim.t == pytest.approx(1.0) and sim.vehicle.ticks == 50
    assert Simulator(track, small()).config.fps == 30.0
    uncapped = Simulator(track, small(fps=0))
    time.sleep(0.15)
    uncapped.advance((0.0, 0.5))
    assert uncapped.t == pytest.approx(0.1)  # a stalled frame moves the car at most 0.1 s
    uncapped.advance(None)
    assert 0.1 < uncapped.t < 0.2  # then the wall time since the last frame


class RecordingDriver:
    def __init__(self):
        self.calls = []

    def step(self, telemetry, now=None):
        self.calls.append((telemetry, now))
        return None, Command(0.2, 0.4, "cruise")


def test_inprocess_sends_and_answers_the_bytes_of_a_lockstep_client(track):
    sim = Simulator(track, small(max_seconds=0.49))
    driver = RecordingDriver()
    run_inprocess(sim, driver)
    assert len(driver.calls) == 15
    # the simulated time travels on the message, with the wire's 4 decimals, and nothing beside it
    assert [tel.time for tel, _ in driver.calls] == [round(k / 30, 4) for k in range(15)]
    assert all(now is None for _, now in driver.calls)
    assert sim.vehicle.wheel_deg == 5.0


@pytest.mark.parametrize("style", ["via", "painted"])
def test_inprocess_and_a_lockstep_drive_server_drive_alike(style):
    """One track, the default driver: in this process and through a real drive server in lockstep,
    the same commands, so the same path to the last millimetre (they once parted after a minute).
    The server settles the driver's put-off work after each answer (the painted road's carriageway
    scan, the kerbed road's look for paint), the in-process loop on the next frame: the same drive."""
    from signlane.config import Config
    from signlane.sim.driver import Driver
    from signlane.sim.server import DriveServer, ServerOptions
    from signlane.world.maps import load_track
    track = load_track("random", style, 3, size="small")
    cfg = SimConfig(width=320, height=240, max_seconds=4.0)
    paths = []
    for how in ("inprocess", "server"):
        sim, path = Simulator(track, cfg), []

        def progress(s, cmd, perception):
            pose = s.vehicle.pose
            path.append((round(pose.x, 6), round(pose.y, 6), round(s.vehicle.wheel_deg, 6)))
        if how == "inprocess":
            with Driver(Config()) as driver:
                run_inprocess(sim, driver, progress)
        else:
            with DriveServer(Config(), ServerOptions(port=0, sync_signs=True, web=False)) as srv:
                run_client(sim, srv.url, lockstep=True, progress=progress)
        paths.append(path)
    assert len(paths[0]) == len(paths[1]) > 100
    assert paths[0] == paths[1]
    start, end = np.array(paths[0][0][:2]), np.array(paths[0][-1][:2])
    assert np.hypot(*(end - start)) > 5.0  # the car drove off (not two cars standing still)


class FakeServer:
    """A WebSocket server that records every message and answers with `reply` (None: never)."""

    def __init__(self, reply: str | None):
        self.reply, self.messages = reply, []
        self.server = serve(self.handle, "127.0.0.1", 0, max_size=None)
        self.thread = threading.Thread(target=self.server.serve_forever, daemon=True)

    def handle(self, ws):
        for message in ws:
            self.messages.append(message)
            if self.reply is not None:
                ws.send(self.reply)

    def __enter__(self):
        self.thread.start()
        return f"ws://127.0.0.1:{self.server.socket.getsockname()[1]}"

    def __exit__(self, *exc):
        self.server.shutdown()
        self.thread.join(10)


def test_clients_send_binary_frames(track):
    lock = Simulator(track, small(max_seconds=0.29))
    server = FakeServer('{"throttle": 0.5, "steering": -0.12}')
    with server as url:
        run_client(lock, url, lockstep=True)
    assert len(server.messages) == 9 and all(isinstance(m, bytes) for m in server.messages)
    times = [parse_number("time", json.loads(m)["time"]) for m in server.messages]
    assert times == pytest.approx([k / 30 for k in range(9)], abs=1e-4)  # lockstep: simulated time, N4
    assert lock.vehicle.wheel_deg == pytest.approx(-3.0) and lock.vehicle.pedal == 0.5

    real = Simulator(track, small(max_seconds=0.29))
    server = FakeServer('{"throttle": 0.5, "steering": -0.12}')
    with server as url:
        run_client(real, url, lockstep=False)
    assert server.messages and all(isinstance(m, bytes) for m in server.messages)
    assert all(tuple(json.loads(m)) == TELEMETRY_KEYS for m in server.messages)  # VIA's bytes: no "time"
    assert real.vehicle.wheel_deg == pytest.approx(-3.0) and real.vehicle.pedal == 0.5  # replies reached the car


def test_real_time_never_waits_for_a_reply(track):
    sim = Simulator(track, small(max_seconds=0.3, fps=60))
    server = FakeServer(None)  # reads every frame, answers none
    with server as url:
        rep = run_client(sim, url, lockstep=False)
    assert rep["time_s"] >= 0.3 and len(server.messages) == sim.frame > 1
    assert sim.vehicle.pedal == 0.0 and sim.vehicle.speed == 0.0  # no reply: no command, the car stays


@pytest.mark.parametrize("text, fps", [("30", 30.0), ("60", 60.0), ("12.5", 12.5), ("uncapped", 0.0), ("0", 0.0)])
def test_fps_flag(text, fps):
    assert fps_arg(text) == fps


@pytest.mark.parametrize("text", ["-1", "nan", "inf", "fast", ""])
def test_fps_flag_refuses(text):
    with pytest.raises(argparse.ArgumentTypeError, match="uncapped"):
        fps_arg(text)
    with pytest.raises(ValueError, match="fps"):
        SimConfig(fps=float("nan") if text == "nan" else -1.0)


def test_a_car_that_drives_off_a_dead_end_is_put_back_turned_round():
    """A straight road that ends both ways, driven straight on: each time the car leaves an end
    the referee counts one off-road event and puts it back at that end facing the other way (put
    back facing the end it would leave again within a few frames, one event after another)."""
    cells = [{"id_inmap": r * 5 + 2, "tile_id": 0, "rot": 0} for r in range(1, 11)]
    track = Track.from_via({"map_name": "stub", "map_size": {"x": 5, "y": 12}, "car_pos": {"x": 2, "y": 2},
                            "cell_datas": cells})
    assert len(track.dead_ends) == 2
    sim = Simulator(track, small(max_seconds=60.0))
    events, headings, ts = 0, [], []
    while sim.t < 40.0:
        sim.advance((0.0, 0.6), dt=1 / 30)
        if sim.score.offroad_events > events:
            events = sim.score.offroad_events
            headings.append(sim.vehicle.pose.heading)
            ts.append(sim.t)
            p = sim._ahead(sim.vehicle.params.wheelbase_m / 2)  # the car's origin, as refereed: back on its lane
            assert abs(sim.course.cross_track(p.x, p.y)) < 0.05
    assert events >= 3  # it drove off both ends, and again
    assert all(abs(abs(b - a) - np.pi) < 0.1 for a, b in zip(headings, headings[1:]))  # turned round each time
    assert min(np.diff(ts)) > 3.0  # a road's length apart, not a few frames
