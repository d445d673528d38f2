"""`signlane run`: the drive stack on a video file (played at its own frame rate) and on a camera
that stops delivering, commands to the actuators; the car always ends on a safe stop."""
import json
import threading

import numpy as np
import pytest

from signlane.cli import main
from signlane.config import Config
from signlane.drive.actuators import ActuatorError, load_actuator
from signlane.drive.run import SteeringSmoother, run_loop
from signlane.drive.sources import CameraSource
from signlane.drive.stack import DriveStack
from signlane.video_out import VideoOut


def render_bend(drive, stretches, folder, side: str):
    """A clean drive into and through a bend (|curvature| > 0.015/m for 12 m), 20 frames/s."""
    path = folder / f"{side}_bend.mp4"
    first = int((stretches[side] - 6.0 - 5.0) / drive.step_m)
    with VideoOut(path, 20, (320, 240)) as video:
        for i in range(first, first + 36):
            video.write(drive.sample(i).image)
    return path


@pytest.fixture(scope="module")
def bend_video(drive, stretches, tmp_path_factory):
    # the drive's left bend is a junction turn (the stack goes straight on there): the right one is a plain bend
    return render_bend(drive, stretches, tmp_path_factory.mktemp("run"), "right")


def commands(text: str) -> list[dict]:
    return [json.loads(line) for line in text.splitlines() if line.strip()]


def test_run_steers_right_on_a_right_bend_and_stops_after_the_last_frame(bend_video, capsys):
    assert main(["run", "--video", str(bend_video), "--actuator", "print", "--no-web", "--no-signs"]) == 0
    cmds = commands(capsys.readouterr().out)
    driven, last = cmds[:-1], cmds[-1]
    assert len(driven) >= 10  # frames the loop had no time for are dropped, as a camera's would be
    steer = np.array([c["steering"] for c in driven])
    assert np.median(steer) > 0.1 and np.mean(steer > 0) >= 0.8, steer.round(2)
    assert all(c["throttle"] > 0 for c in driven)
    assert last["throttle"] == 0.0 and last["steering"] == 0.0 and last["state"].startswith("stop: end of video")


class StallingCamera:
    """A capture that delivers frames, then hangs in read() (a camera unplugged mid-run) until
    `resume` is set, then delivers again."""

    def __init__(self, frames, stall_after: int):
        self.frames, self.stall_after, self.n = frames, stall_after, 0
        self.resume, self.released = threading.Event(), False

    def read(self):
        if self.n == self.stall_after:
            self.resume.wait()
        image = self.frames[self.n % len(self.frames)]
        self.n += 1
        threading.Event().wait(0.03)
        return True, image.copy()

    def release(self):
        self.released = True


class Recorder:
    def __init__(self):
        self.commands, self.closed = [], False
        self.stopped = threading.Event()

    def step(self, command):
        self.commands.append(command)
        if command.state.startswith("stop: no frame"):
            self.stopped.set()

    def close(self):
        self.closed = True


def test_a_camera_that_stops_delivering_stops_the_car(drive, stretches):
    first = int((stretches["straight"] - 5.0) / drive.step_m)
    frames = [drive.sample(first + i).image for i in range(6)]
    camera = StallingCamera(frames, stall_after=8)
    actuator, stop = Recorder(), threading.Event()
    source = CameraSource("fake", capture=camera).start()
    stack = DriveStack(Config.load(None, ["signs.enabled=false"]))
    totals = {}

    def go():
        totals["run"] = run_loop(source, stack, actuator, smoothing=0.5, frame_timeout_s=0.4, stop=stop)
    loop = threading.Thread(target=go)
    loop.start()
    try:
        assert actuator.stopped.wait(60), "no safe stop while the camera was silent"
        before = list(actuator.commands)
        assert before[-1].throttle == 0.0 and before[-1].steering == 0.0
        assert any(c.throttle > 0 for c in before[:-1])  # it was driving until the camera went quiet
        camera.resume.set()  # the camera comes back: the car drives on
        for _ in range(200):
            if len(actuator.commands) > len(before) + 3:
                break
            threading.Event().wait(0.05)
        assert any(c.throttle > 0 for c in actuator.commands[len(before):])
    finally:
        camera.resume.set()
        stop.set()
        loop.join(30)
    assert actuator.commands[-1].throttle == 0.0 and actuator.commands[-1].state == "stop: stopped"
    assert actuator.closed and totals["run"].timeouts == 1


def test_a_users_actuator_class(bend_video, tmp_path, monkeypatch, capsys):
    (tmp_path / "mycar.py").write_text(
        "import json\n"
        "class Motors:\n"
        "    def __init__(self):\n"
        "        self.f = open('motors.jsonl', 'w')\n"
        "    def step(self, command):\n"
        "        self.f.write(json.dumps([command.steering, command.throttle, command.state]) + '\\n')\n"
        "    def close(self):\n"
        "        self.f.close()\n")
    monkeypatch.chdir(tmp_path)
    monkeypatch.syspath_prepend(str(tmp_path))
    assert main(["run", "--video", str(bend_video), "--actuator", "mycar:Motors", "--no-web", "--no-signs"]) == 0
    got = [json.loads(line) for line in (tmp_path / "motors.jsonl").read_text().splitlines()]
    assert len(got) >= 10 and got[-1][:2] == [0.0, 0.0] and got[-1][2].startswith("stop: end of video")
    assert capsys.readouterr().out == ""  # the commands went to the class, not to stdout


@pytest.mark.parametrize("args, says", [
    (["--camera", "7"], "camera 7: cannot open it"),
    (["--video", "missing.mp4"], "video missing.mp4: no such file"),
    (["--video", "{notvideo}"], "cannot read a frame from it"),
    (["--video", "{video}", "--actuator", "servo"], "actuator 'servo': expected print, udp:HOST:PORT or module:Class"),
    (["--video", "{video}", "--actuator", "udp:car:0"], "port 1..65535"),
    (["--video", "{video}", "--actuator", "json:Motor"], "module 'json' has no 'Motor'"),
])
def test_bad_sources_and_actuators_get_one_line(args, says, bend_video, tmp_path, capsys):
    (tmp_path / "notes.mp4").write_text("not a video")
    args = [a.format(video=bend_video, notvideo=tmp_path / "notes.mp4") for a in args]
    assert main(["run", *args, "--no-web"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and says in err[0], err


def test_actuator_specs_and_smoothing():
    assert type(load_actuator("print")).__name__ == "PrintActuator"
    udp = load_actuator("udp:127.0.0.1:9")
    udp.close()
    with pytest.raises(ActuatorError):
        load_actuator("udp:127.0.0.1")
    s = SteeringSmoother(0.5)
    assert [s.step(v) for v in (0.4, 0.0, 0.0)] == [0.4, 0.2, 0.1]
    with pytest.raises(ValueError):
        SteeringSmoother(0.0)


def test_run_serves_the_monitor_and_no_simulator_socket(bend_video):
    import urllib.request
    from websockets.exceptions import ConnectionClosed
    from websockets.sync.client import connect
    from signlane.drive.monitor import Monitor
    from signlane.drive.monitor_server import MonitorServer
    from signlane.drive.sources import VideoSource
    monitor, actuator = Monitor(), Recorder()
    with MonitorServer(monitor, port=0) as srv:
        run_loop(VideoSource(bend_video).start(), DriveStack(Config.load(None, ["signs.enabled=false"])), actuator,
                 monitor)
        with urllib.request.urlopen(f"http://127.0.0.1:{srv.port}/api/state", timeout=10) as r:
            state = json.loads(r.read())
        with connect(f"ws://127.0.0.1:{srv.port}/") as ws, pytest.raises(ConnectionClosed) as closed:
            ws.recv(timeout=10)
    driven = actuator.commands[:-1]  # the last is the stop at the end of the video
    assert state["seq"] == len(driven) and state["command"]["steering"] == round(driven[-1].steering, 4)
    assert state["source"] == f"video {bend_video}" and state["encoded"] == 0
    assert closed.value.rcvd.code == 1008
