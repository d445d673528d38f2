"""The live monitor on the drive server's port: its page and read-only endpoints over plain HTTP,
the viewer stream (newest frame first, nothing encoded while nobody watches, a viewer that does
not ack gets no more frames), topics, and control only with allow_control."""
import json
import time
import urllib.error
import urllib.request

import cv2
import numpy as np
import pytest
from websockets.sync.client import connect

from signlane.drive.web import is_loopback
from signlane.sim.protocol import encode_jpeg, encode_telemetry
from signlane.sim.server import DriveServer, ServerOptions
from signlane.types import Command, Frame, LaneEstimate, Perception


class FakeDriver:
    """Answers at once with a fixed lane and command: the monitor, not perception, is under test."""

    def __init__(self):
        self.n = 0

    def step(self, tel, now=None):
        self.n += 1
        h, w = tel.image_bgr.shape[:2]
        left = np.array([[w * 0.3, h - 1.0], [w * 0.45, h * 0.5]])
        right = np.array([[w * 0.7, h - 1.0], [w * 0.55, h * 0.5]])
        mask = np.zeros((h, w), np.uint8)
        mask[h // 2:, w // 3: 2 * w // 3] = 255
        road = np.zeros((h // 2, w // 2), np.uint8)  # at the lane copy's size, as road-edges gives it
        road[h // 4:, :] = 255
        lane = LaneEstimate("fake", True, 0.1, 0.0, left=left, right=right, debug_mask=mask, basis="edges",
                            drivable_mask=road)
        return Perception(Frame(tel.image_bgr, self.n * 0.05, self.n), lane, ()), Command(0.25, 0.3, "cruise")

    def close(self):
        pass


def frame_msg(i: int) -> bytes:
    img = np.full((240, 320, 3), 90, np.uint8)
    img[:, (i * 7) % 300:(i * 7) % 300 + 20] = (0, 200, 255)
    return encode_telemetry(0.0, 0.5, 5.0, encode_jpeg(img), time=0.05 * i)


def drive(url: str, n: int, start: int = 0) -> None:
    with connect(url, max_size=None) as ws:
        for i in range(start, start + n):
            ws.send(frame_msg(i))
            json.loads(ws.recv(timeout=20))


def get(url: str):
    with urllib.request.urlopen(url, timeout=10) as r:
        return r.status, r.headers.get("Content-Type"), r.read()


def status_of(url: str) -> int:
    """The status of a request that fails, its connection closed (an open one holds up the
    server's shutdown by its close timeout)."""
    try:
        get(url)
    except urllib.error.HTTPError as e:
        e.close()
        return e.code
    return 200


@pytest.fixture()
def server():
    with DriveServer(options=ServerOptions(port=0), driver_factory=FakeDriver) as srv:
        yield srv


def http(srv) -> str:
    return f"http://127.0.0.1:{srv.port}"


def test_page_and_endpoints_on_the_drive_port(server):
    base = http(server)
    assert get(f"{base}/api/state")[2] and json.loads(get(f"{base}/api/state")[2])["seq"] == 0
    drive(server.url, 5)
    for path in ("/", "/web/index.html"):  # VIA's Visualizer lives at /web/index.html
        status, ctype, body = get(base + path)
        assert status == 200 and ctype.startswith("text/html") and b"signlane monitor" in body
    js = get(f"{base}/monitor.js")[2]
    page = get(f"{base}/")[2] + js
    assert b"https://" not in page and b"http://" not in page  # nothing from outside the machine (no CDN)
    state = json.loads(get(f"{base}/api/state")[2])
    assert state["seq"] == 5 and state["command"] == {"steering": 0.25, "throttle": 0.3, "state": "cruise"}
    assert state["lane"]["left"][0] == [96.0, 239.0] and (state["width"], state["height"]) == (320, 240)
    assert len(state["samples"]) == 5 and state["samples"][-1][2] == 0.25
    status, ctype, body = get(f"{base}/api/frame.jpg?topic=rgb")
    img = cv2.imdecode(np.frombuffer(body, np.uint8), cv2.IMREAD_COLOR)
    assert ctype == "image/jpeg" and img.shape == (240, 320, 3)
    mask = cv2.imdecode(np.frombuffer(get(f"{base}/api/frame.jpg?topic=mask")[2], np.uint8), cv2.IMREAD_GRAYSCALE)
    assert mask[200, 160] > 200 and mask[50, 20] < 50  # the lane method's mask, at the frame's size
    road = cv2.imdecode(np.frombuffer(get(f"{base}/api/frame.jpg?topic=drivable")[2], np.uint8), cv2.IMREAD_GRAYSCALE)
    assert road.shape == (240, 320) and road[200, 20] > 200 and road[60, 160] < 50  # scaled to the frame
    assert status_of(f"{base}/api/frame.jpg?topic=nope") == 404
    assert status_of(f"{base}/secrets") == 404


def test_nothing_is_encoded_while_nobody_watches(server):
    drive(server.url, 20)
    state = json.loads(get(f"{http(server)}/api/state")[2])
    assert state["seq"] == 20 and state["encoded"] == 0 and state["viewers"] == 0


def test_a_viewer_gets_the_newest_frame_and_nothing_until_it_acks(server):
    drive(server.url, 3)
    with connect(f"ws://127.0.0.1:{server.port}/monitor") as viewer:
        state = json.loads(viewer.recv(timeout=10))
        jpeg = viewer.recv(timeout=10)
        assert state["seq"] == 3 and state["topic"] == "rgb" and state["aligned"] is True
        assert isinstance(jpeg, bytes) and cv2.imdecode(np.frombuffer(jpeg, np.uint8), 1).shape == (240, 320, 3)
        drive(server.url, 10, start=3)  # the car goes on while the viewer has not acked
        with pytest.raises(TimeoutError):
            viewer.recv(timeout=0.5)
        viewer.send(json.dumps({"ack": state["seq"]}))
        newer = json.loads(viewer.recv(timeout=10))
        viewer.recv(timeout=10)
        assert newer["seq"] == 13  # the newest, not the next: frames in between were never encoded
        assert [s[0] for s in newer["samples"]] == list(range(4, 14))  # the plots still get every frame's numbers
        viewer.send(json.dumps({"topic": "birdseye"}))
        switched = json.loads(viewer.recv(timeout=10))
        bev = cv2.imdecode(np.frombuffer(viewer.recv(timeout=10), np.uint8), 1)
        assert switched["topic"] == "birdseye" and switched["aligned"] is False and bev.shape == (120, 160, 3)
        viewer.send(json.dumps({"topic": "warp-drive"}))
        assert "unknown topic" in json.loads(viewer.recv(timeout=10))["error"]
        state = json.loads(get(f"{http(server)}/api/state")[2])
        assert state["viewers"] == 1 and state["encoded"] == 3


def test_control_needs_allow_control(tmp_path, monkeypatch, server):
    monkeypatch.chdir(tmp_path)
    drive(server.url, 2)
    with connect(f"ws://127.0.0.1:{server.port}/monitor") as viewer:
        viewer.recv(timeout=10), viewer.recv(timeout=10)
        viewer.send(json.dumps({"save": True}))
        assert "--allow-control" in json.loads(viewer.recv(timeout=10))["error"]
    assert not list(tmp_path.iterdir())
    with DriveServer(options=ServerOptions(port=0, allow_control=True), driver_factory=FakeDriver) as srv:
        drive(srv.url, 2)
        with connect(f"ws://127.0.0.1:{srv.port}/monitor") as viewer:
            viewer.recv(timeout=10), viewer.recv(timeout=10)
            viewer.send(json.dumps({"save": True}))
            saved = json.loads(viewer.recv(timeout=10))
    assert saved["type"] == "saved"
    png = tmp_path / saved["path"]
    assert cv2.imread(str(png)).shape == (240, 320, 3)
    assert json.loads(png.with_suffix(".json").read_text())["seq"] == 2


def test_no_web_serves_no_page():
    with DriveServer(options=ServerOptions(port=0, web=False), driver_factory=FakeDriver) as srv:
        assert status_of(f"http://127.0.0.1:{srv.port}/") == 426  # websockets' own answer: upgrade required
        drive(srv.url, 2)  # the simulator's socket as before


def test_loopback_addresses():
    assert is_loopback("127.0.0.1") and is_loopback("::1") and is_loopback("localhost")
    assert not is_loopback("0.0.0.0") and not is_loopback("") and not is_loopback("192.168.1.5")
