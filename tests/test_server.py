"""The drive server over real WebSockets: valid frames (binary, as VIA sends them, or text) get
commands; no bad input stops it."""
import base64
import json
import logging
import socket
import struct
import threading
import time
from dataclasses import replace

import cv2
import numpy as np
import pytest
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect

from lane_helpers import loop_scene
from signlane.camera import via_camera
from signlane.cli import main as cli_main
from signlane.config import Config
from signlane.sim.drive_stats import ErrorLog
from signlane.sim.protocol import MPS_PER_MPH, SAFE_COMMAND, encode_jpeg, encode_telemetry
from signlane.sim.server import DriveServer, ServerOptions
from signlane.types import Command, LaneEstimate, Perception
from signlane.world.sampling import FrameSampler, SamplerConfig

MAX_BYTES = 256 * 1024  # small, so over-limit messages are cheap to make
SAFE = json.loads(SAFE_COMMAND)


def tel(image, i: int = 0, speed: float = 5.0) -> bytes:
    """A binary frame as signlane's lockstep simulator sends it (VIA's, plus the "time" key)."""
    return encode_telemetry(0.0, 0.5, speed, encode_jpeg(image), time=0.05 * i)


@pytest.fixture(scope="module")
def frames():
    smp = FrameSampler(11, SamplerConfig(320, 240, effects="clean", randomise=False, lateral_m=0.1, heading_deg=1))
    return [smp.sample(i).image for i in range(4)]


@pytest.fixture(scope="module")
def messages(frames):
    return [tel(f, i) for i, f in enumerate(frames)]


@pytest.fixture(scope="module")
def server():
    cfg = Config()
    with DriveServer(cfg, ServerOptions(port=0, max_bytes=MAX_BYTES)) as srv:
        yield srv


def ask(ws, message) -> dict:
    ws.send(message)
    answer = ws.recv(timeout=20)
    assert isinstance(answer, str)
    return json.loads(answer)


def assert_command(cmd: dict, driving: bool = True) -> None:
    assert set(cmd) == {"throttle", "steering"}
    assert all(type(v) in (int, float) for v in cmd.values())  # plain numbers, not strings
    assert -1.0 <= cmd["steering"] <= 1.0 and 0.0 <= cmd["throttle"] <= 1.0
    if driving:
        assert cmd["throttle"] > 0.0  # the lane is seen on these clean frames: the car goes


def test_valid_frames_get_commands(server, messages):
    with connect(server.url) as ws:
        for m in messages:
            assert_command(ask(ws, m))


def test_vias_exact_frames_get_text_answers(server, frames):
    """What VIA sends: binary frames, N4 strings, speed in mph, no "time" key; as text frames and
    from a comma-decimal machine too. Each gets a plain-number text answer, the same for all."""
    jpegs = [encode_jpeg(f) for f in frames]
    assert json.loads(encode_telemetry(-1.25, 0.5, 5.0, jpegs[0]))["speed"] == "11.1847"  # mph on the wire
    answers = {}
    for form in ("binary", "text", "comma"):
        with connect(server.url) as ws:
            out = []
            for i, jpeg in enumerate(jpegs):
                msg = encode_telemetry(-1.25 * i, 0.5 * (i % 2), 5.0, jpeg, decimal="," if form == "comma" else ".")
                assert b'"time"' not in msg and b" " not in msg
                out.append(ask(ws, msg.decode("utf-8") if form == "text" else msg))
            answers[form] = out
    for cmd in answers["binary"]:
        assert_command(cmd)
    assert answers["text"] == answers["binary"] == answers["comma"]


def test_steering_turns_back_towards_the_lane_centre():
    route, renderer = loop_scene()
    cam = via_camera(320, 240)  # the camera the server's defaults assume
    with DriveServer(options=ServerOptions(port=0)) as srv:
        for lateral, sign in ((0.9, -1), (-0.9, 1)):  # right of centre -> steer left (negative), and back
            with connect(srv.url) as ws:
                img = renderer.render_on_route(route, 105.0, cam, lateral_m=lateral).image
                cmd = ask(ws, tel(img))
                assert_command(cmd)
                assert cmd["steering"] * sign > 0.05, (lateral, cmd)


def _jpeg_b64(img) -> str:
    return base64.b64encode(encode_jpeg(img)).decode()


def _bad_inputs(good_frame):
    good = json.loads(tel(good_frame))

    def with_(**kw):
        return json.dumps({**good, **kw})

    def without(key):
        return json.dumps({k: v for k, v in good.items() if k != key})
    return {
        "malformed json": '{"steering_angle": "0.0", "throttle": ',
        "json array": "[1, 2, 3]",
        "missing image": without("image"),
        "missing speed": without("speed"),
        "non-numeric speed": with_(speed="fast"),
        "nan throttle": with_(throttle="NaN"),
        "nan literal": with_(speed=float("nan")),
        "infinite angle": with_(steering_angle="-inf"),
        "huge integer": with_(speed=10 ** 400),
        "non-base64 image": with_(image="this is *not* base64!"),
        "non-jpeg bytes": with_(image=base64.b64encode(b"GIF89a but not really" * 10).decode()),
        "empty image": with_(image=""),
        "1x1 image": with_(image=_jpeg_b64(np.zeros((1, 1, 3), np.uint8))),
        "comma without 4 decimals": with_(speed="5,0"),
        "binary frame not UTF-8": tel(good_frame).replace(b'"0.5000"', b'"0.5\xff00"'),
        "binary frame, bad number": with_(steering_angle="1.2.3").encode(),
        "over the size limit": with_(pad="x" * (MAX_BYTES + 10)),
    }


def test_every_bad_input_gets_a_safe_answer_and_one_log_line(server, frames, messages, caplog):
    bad = _bad_inputs(frames[0])
    caplog.set_level(logging.INFO, logger="signlane.drive")
    with connect(server.url, max_size=None) as ws:
        for name, message in bad.items():
            caplog.clear()
            assert ask(ws, message) == SAFE, name
            lines = [r for r in caplog.records if r.levelno >= logging.WARNING]
            assert len(lines) == 1, (name, [r.getMessage() for r in lines])
            assert "\n" not in lines[0].getMessage()
            assert_command(ask(ws, messages[1]))  # and the next valid frame is driven again


def test_size_limit_applies_to_binary_frames(messages):
    big = json.dumps({**json.loads(messages[0]), "pad": "x" * MAX_BYTES}).encode()
    with DriveServer(options=ServerOptions(port=0, max_bytes=MAX_BYTES), driver_factory=lambda: SlowDriver(0.0)) as srv:
        with connect(srv.url) as ws:
            assert ask(ws, big) == SAFE
            assert ask(ws, messages[0]) == {"throttle": 0.5, "steering": 0.25}
    assert srv.totals["bad"] == 1


def test_repeated_errors_are_rate_limited(messages, caplog):
    caplog.set_level(logging.INFO, logger="signlane.drive")
    # a server of its own: the shared one may have logged this problem moments ago
    with DriveServer(options=ServerOptions(port=0), driver_factory=lambda: SlowDriver(0.0)) as srv:
        with connect(srv.url) as ws:
            for _ in range(6):
                assert ask(ws, "zebra zebra") == SAFE
            assert_command(ask(ws, messages[0]))
    lines = [r.getMessage() for r in caplog.records if "not JSON" in r.getMessage()]
    # the first, and when the client leaves, how often it recurred
    assert len(lines) == 2 and lines[1].endswith("(repeated 5 times in the last 0 s)"), lines


def test_error_log_counts_repeats():
    lines = []
    errors = ErrorLog(window_s=10.0, logger=logging.getLogger("test.errorlog"))
    errors.logger.warning = lambda fmt, *a: lines.append(fmt % a)
    assert errors.warning("message of 900 bytes is over", now=0.0, who="client 1")
    assert not errors.warning("message of 901 bytes is over", now=5.0, who="client 1")  # same problem, numbers aside
    assert errors.warning("other problem", now=6.0, who="client 1")
    assert errors.warning("message of 900 bytes is over", now=11.0, who="client 1")
    assert lines[-1] == "client 1: message of 900 bytes is over (and 1 more like it in the last 11 s)"


def test_huge_message_closes_that_connection_only(server, messages):
    with connect(server.url, max_size=None) as ws:
        ws.send("x" * (3 * MAX_BYTES))  # over websockets' own limit (2x ours): closed with 1009
        with pytest.raises(ConnectionClosed) as e:
            ws.recv(timeout=20)
        assert e.value.rcvd is not None and e.value.rcvd.code == 1009
    with connect(server.url) as ws:  # the server still serves
        assert_command(ask(ws, messages[0]))


def raw_client(port: int) -> socket.socket:
    """A bare TCP socket that has done the WebSocket handshake: it can then send anything."""
    sock = socket.create_connection(("127.0.0.1", port), timeout=10)
    sock.sendall(b"GET / HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                 b"Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n")
    reply = b""
    while b"\r\n\r\n" not in reply:
        reply += sock.recv(4096)
    assert reply.startswith(b"HTTP/1.1 101")
    return sock


def text_frame(payload: bytes, declared: int | None = None) -> bytes:
    """A masked text frame (zero mask key, so the payload goes as is) claiming `declared` bytes."""
    return bytes([0x81, 0x80 | 127]) + struct.pack("!Q", declared or len(payload)) + b"\0\0\0\0" + payload


def test_client_disconnecting_mid_frame(server, messages, caplog):
    caplog.set_level(logging.INFO, logger="signlane.drive")
    sock = raw_client(server.port)
    sock.sendall(text_frame(b"{" * 5_000, declared=100_000))
    sock.close()  # gone without finishing the frame or closing the connection
    sock = raw_client(server.port)
    sock.sendall(text_frame(messages[0]))
    sock.close()  # gone while its frame is being driven, answer unread
    with connect(server.url) as ws:
        assert_command(ask(ws, messages[0]))
    time.sleep(0.2)  # the server notices the second drop once that frame's driving ends
    dropped = [r.getMessage() for r in caplog.records if "dropped" in r.getMessage()]
    assert len(dropped) == 2 and all("no close frame" in m for m in dropped), dropped


def test_several_clients_at_once_each_with_its_own_driver(server, messages):
    """Four clients send the same frames at the same time; each sees what a lone client sees,
    so no driver state (tracking, smoothing) leaks between connections."""
    with connect(server.url) as ws:
        alone = [ask(ws, m) for m in messages]
    results, errors = {}, []

    def client(k):
        try:
            with connect(server.url) as ws:
                results[k] = [ask(ws, m) for m in messages]
        except Exception as e:  # reported below; a thread's exception would vanish
            errors.append(e)
    threads = [threading.Thread(target=client, args=(k,)) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60)
    assert not errors
    assert len(results) == 4 and all(r == alone for r in results.values())


class SlowDriver:
    """A stand-in driver: slow, and raises on a frame whose speed is 13 m/s."""

    def __init__(self, delay_s: float = 0.15):
        self.delay_s = delay_s

    def step(self, t):
        if abs(t.speed_mps - 13.0) < 1e-3:
            raise RuntimeError("boom")
        time.sleep(self.delay_s)
        lane = LaneEstimate("fake", True)
        return Perception(None, lane), Command(0.25, 0.5, "cruise")

    def close(self):
        pass


def test_busy_driver_answers_every_frame_at_once_without_backlog(frames):
    with DriveServer(options=ServerOptions(port=0), driver_factory=SlowDriver) as srv:
        with connect(srv.url) as ws:
            for i in range(5):  # back to back, as the simulator does: it never waits
                ws.send(tel(frames[0], i))
            answers = [json.loads(ws.recv(timeout=20)) for _ in range(5)]
            # four frames arrived while the first was driven: answered at once with the latest command
            # (safe: nothing driven yet), ahead of the driven answer, not queued behind it
            assert answers[:4] == [SAFE] * 4 and answers[4] == {"throttle": 0.5, "steering": 0.25}
            assert ask(ws, tel(frames[0], speed=13.0)) == SAFE  # a driver exception: safe answer
            assert ask(ws, tel(frames[0])) == {"throttle": 0.5, "steering": 0.25}  # and it goes on
    counts = {k: srv.totals[k] for k in ("frames", "processed", "skipped", "bad")}
    assert counts == {"frames": 7, "processed": 2, "skipped": 4, "bad": 1}
    # the run's latency split: decode and perceive of driven frames, answer of every answered one
    assert 0 < srv.totals["decode_ms_median"] <= srv.totals["decode_ms_p99"]
    assert srv.totals["perceive_ms_median"] >= 0 and srv.totals["answer_ms_p99"] >= srv.totals["answer_ms_median"]


def test_each_connection_reports_its_own_latency_split(frames, caplog):
    """Every connection's decode / perceive / answer medians and p99s go into its closing log line
    and the server's totals (with the path it asked for): a benchmark reads the runs it made at
    30 frames/s apart from its floods."""
    caplog.set_level(logging.INFO, logger="signlane.drive")
    with DriveServer(options=ServerOptions(port=0), driver_factory=lambda: SlowDriver(0.02)) as srv:
        for path, n in (("/first", 3), ("/second", 5)):
            with connect(srv.url + path) as ws:
                for i in range(n):
                    assert ask(ws, tel(frames[0], i)) == {"throttle": 0.5, "steering": 0.25}
    first, second = srv.totals["connections"]
    assert (first["path"], first["frames"], second["path"], second["frames"]) == ("/first", 3, "/second", 5)
    for c in (first, second):
        assert c["driven"] == c["frames"]
        # the driver sleeps 20 ms a frame: its perceive time, inside the answer's
        assert 20 <= c["perceive_ms_median"] <= c["answer_ms_median"] <= c["answer_ms_p99"]
        assert 0 < c["decode_ms_median"] < c["answer_ms_median"]
    lines = [r.getMessage() for r in caplog.records if "disconnected after" in r.getMessage()]
    assert len(lines) == 2 and all("perceive median" in x and "answer median" in x for x in lines)


class AfterAnswerDriver(SlowDriver):
    """Puts work off until its answer is out (answered()), as the drive stack does; the work of
    the frame at 7 m/s fails."""

    def __init__(self):
        super().__init__(0.0)
        self.log = []

    def step(self, t):
        self.log.append(("step", t.speed_mps))
        self.speed = t.speed_mps
        return super().step(t)

    def answered(self):
        time.sleep(0.05)  # slower than the round trip: the next frame must wait for it
        self.log.append(("after", self.speed))
        if abs(self.speed - 7.0) < 1e-3:
            raise RuntimeError("settle failed")


def test_the_drivers_work_after_an_answer_runs_before_the_next_frame_and_a_failure_is_reported(frames, caplog):
    drivers = []
    with DriveServer(options=ServerOptions(port=0), driver_factory=lambda: drivers.append(AfterAnswerDriver())
                     or drivers[-1]) as srv:
        with caplog.at_level(logging.WARNING), connect(srv.url) as ws:
            for speed in (5.0, 7.0, 9.0):  # lockstep: each frame right after the last answer
                assert ask(ws, tel(frames[0], speed=speed)) == {"throttle": 0.5, "steering": 0.25}
    log = [(what, round(speed, 3)) for what, speed in drivers[-1].log]  # (drivers[0]: the start-up probe's)
    assert log[:5] == [("step", 5.0), ("after", 5.0), ("step", 7.0), ("after", 7.0), ("step", 9.0)]
    assert srv.totals["processed"] == 3 and srv.totals["skipped"] == 0  # none answered from the latest
    assert any("driver failed after its answer: RuntimeError: settle failed" in r.getMessage() for r in caplog.records)


def test_record_writes_a_readable_dataset(frames, messages, tmp_path):
    rec, show = tmp_path / "rec", tmp_path / "show"
    opts = ServerOptions(port=0, record=rec, show_every=2, show_dir=show)
    with DriveServer(replace(Config(), signs=replace(Config().signs, enabled=False)), opts) as srv:
        with connect(srv.url) as ws:
            answers = [ask(ws, m) for m in messages]
            assert ask(ws, "bad frame") == SAFE  # not recorded
    manifest = json.loads((rec / "manifest.json").read_text())
    assert manifest["generator"] == "signlane.drive" and manifest["counts"] == {"frames": 4, "clients": 1}
    assert manifest["config"]["signs"]["enabled"] is False
    lines = [json.loads(x) for x in (rec / "drive.jsonl").read_text().splitlines()]
    assert [x["id"] for x in lines] == [f"c1-{i:06d}" for i in range(4)]
    for i, (line, answer, msg) in enumerate(zip(lines, answers, messages)):
        assert line["command"]["steering"] == pytest.approx(answer["steering"], abs=1e-4)
        assert line["command"]["throttle"] == pytest.approx(answer["throttle"], abs=1e-4)
        # SI units in the recording: m/s from the mph on the wire (4 decimals of mph)
        assert line["telemetry"]["speed_mps"] == pytest.approx(5.0, abs=0.5e-4 * MPS_PER_MPH)
        assert (line["telemetry"]["wheel_deg"], line["telemetry"]["pedal"]) == (0.0, 0.5)
        assert line["telemetry"]["time"] == pytest.approx(0.05 * i)
        assert line["lane"]["method"] == Config().lanes.method
        jpeg = (rec / line["image"]).read_bytes()
        assert jpeg == base64.b64decode(json.loads(msg)["image"])  # the simulator's bytes, unchanged
        assert cv2.imread(str(rec / line["image"])).shape == (240, 320, 3)
    shown = sorted(p.name for p in show.iterdir())
    assert shown == ["c1-000000.jpg", "c1-000002.jpg"]
    assert not [p for p in rec.rglob("*") if p.name.endswith(".tmp")]


def test_record_refuses_a_used_folder(tmp_path, capsys):
    (tmp_path / "old.txt").write_text("x")
    assert cli_main(["drive", "--port", "0", "--record", str(tmp_path)]) == 2
    assert "not empty" in capsys.readouterr().err


def test_cli_rejects_an_unknown_lane_method(capsys):
    assert cli_main(["drive", "--port", "0", "--lanes", "nope"]) == 2
    assert "nope" in capsys.readouterr().err


def test_a_recording_the_pilot_steers_is_labelled_with_what_the_planner_would_send(frames, tmp_path):
    """With `--set pilot.model=...` the sent steering is the pilot's; the label (top-level
    steering, teacher) is the planner's own command of the same frame, so such a drive trains
    like a DAgger drive."""
    rec = tmp_path / "rec"
    cfg = Config.load(None, ["pilot.model=shipped", "signs.enabled=false"])
    with DriveServer(cfg, ServerOptions(port=0, record=rec)) as srv:
        with connect(srv.url) as ws:
            answers = [ask(ws, tel(f, i)) for i, f in enumerate(frames)]
    lines = [json.loads(x) for x in (rec / "drive.jsonl").read_text().splitlines()]
    assert len(lines) == len(frames)
    for line, answer in zip(lines, answers):
        assert line["command"]["steering"] == pytest.approx(answer["steering"], abs=1e-4)
        assert line["student"] == pytest.approx(answer["steering"], abs=1e-4) and line["steered_by"] == "student"
        assert line["steering"] == line["teacher"]["steering"]
    # the pilot and the planner disagree somewhere on these frames: the label is not the sent command
    assert max(abs(x["teacher"]["steering"] - x["command"]["steering"]) for x in lines) > 0.01
