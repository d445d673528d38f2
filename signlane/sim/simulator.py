"""signlane's local VIA-compatible simulator: the world renderer plus a kinematic car.

`Simulator` renders the camera view at the car's pose, sends it in VIA's telemetry format,
applies the answer with VIA's control semantics and referees the drive (signlane/sim/course.py).
Two ways to run it:
Both call `progress(sim, command, perception)` after each frame (perception None when remote).
- `run_inprocess(sim, driver)`: lockstep with a Driver object in the same process (tests, demo);
- `run_client(sim, url, lockstep)`: as a WebSocket client of a drive server, in lockstep (waits
  for each answer: deterministic) or real time (a fixed frame rate; it never waits, and acts on
  the newest answer it has, as VIA does).
"""
from __future__ import annotations

import asyncio
import logging
import time
from dataclasses import dataclass, field

import numpy as np

from signlane.camera import VIA_CAMERA_FORWARD_M, via_camera
from signlane.sim.course import CourseTracker
from signlane.sim.protocol import ProtocolError, decode_command, decode_telemetry, encode_jpeg, encode_telemetry
from signlane.sim.score import Score
from signlane.sim.vehicle import Vehicle, VehicleParams
from signlane.types import Command
from signlane.world.effects import Effects
from signlane.world.render import Renderer
from signlane.world.route import Pose, Route
from signlane.world.scene import build_scene
from signlane.world.track import Track

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class SimConfig:
    width: int = 640
    height: int = 480
    fps: float = 20.0
    jpeg_quality: int = 90
    effects: str = "clean"
    looks_seed: int = 0
    random_looks: bool = False
    laps: int = 1
    max_seconds: float = 600.0
    vehicle: VehicleParams = field(default_factory=VehicleParams)
    send_time: bool = True  # add the "time" key (simulation seconds) to telemetry
    # VIA's camera sits 0.1 m ahead of the car's origin, which is midway between the axles; the
    # car's pose is its rear axle's
    camera_forward_m: float = VIA_CAMERA_FORWARD_M


def start_pose(track: Track, wheelbase_m: float) -> tuple[Pose, object, object]:
    """Where VIA puts the car: its origin at the centre of the map's car_pos cell, facing along the
    road there (north on VIA's maps), on the ego lane; returns the rear axle's pose, the start
    tile and the port the car drives in by."""
    tile, entry, exit_, xy = track.start_state()
    pts = track.centreline(tile, entry, exit_)
    i = int(np.argmin(np.hypot(*(pts - xy).T)))
    d = pts[min(i + 1, len(pts) - 1)] - pts[max(i - 1, 0)]
    heading = float(np.arctan2(d[1], d[0]))
    fwd = np.array([np.cos(heading), np.sin(heading)])
    right = np.array([fwd[1], -fwd[0]])
    origin = xy + right * track.style.ego_lane_offset()
    rear = origin - fwd * wheelbase_m / 2
    return Pose(float(rear[0]), float(rear[1]), heading), tile, entry


class Simulator:
    def __init__(self, track: Track, config: SimConfig | None = None):
        self.config = c = config or SimConfig()
        self.track = track
        self.renderer = Renderer(build_scene(track, seed=c.looks_seed, randomise=c.random_looks))
        self.camera = via_camera(c.width, c.height)
        pose, tile, entry = start_pose(track, c.vehicle.wheelbase_m)
        self.vehicle = Vehicle(pose, c.vehicle)
        self.course = CourseTracker(track, tile, entry)
        self.score = Score(track.style.lane_width, track.style.offroad_m)
        self.t = 0.0
        self.frame = 0
        self.path: list[tuple[float, float]] = []
        self.last_image: np.ndarray | None = None
        self._effects = Effects.named(c.effects)

    @property
    def done(self) -> bool:
        return self.course.laps >= self.config.laps or self.t >= self.config.max_seconds

    def observe(self) -> str:
        """Render the frame at the current pose and return the telemetry message."""
        v = self.vehicle
        rng = np.random.default_rng([self.config.looks_seed, self.frame])
        self.last_image = self.renderer.render(self._ahead(self.config.camera_forward_m + v.params.wheelbase_m / 2),
                                               self.camera, self._effects, rng).image
        jpeg = encode_jpeg(self.last_image, self.config.jpeg_quality)
        return encode_telemetry(v.wheel_deg, v.throttle, v.speed, jpeg, self.t if self.config.send_time else None)

    def advance(self, steering: float, throttle: float, latency_ms: float | None = None) -> None:
        """Apply a command for one frame period and referee the result."""
        dt = 1.0 / self.config.fps
        self.vehicle.step(steering, throttle, dt)
        self.t += dt
        self.frame += 1
        p = self._ahead(self.vehicle.params.wheelbase_m / 2)  # the car's origin, as VIA's referee would see it
        self.path.append((p.x, p.y))
        cte = self.course.update(self.t, p.x, p.y, p.heading, self.vehicle.speed)
        if self.score.frame(self.t, cte, self.vehicle.speed, latency_ms):
            self._intervene()

    def _ahead(self, dist_m: float) -> Pose:
        """The point dist_m ahead of the rear axle (the car's origin, its camera)."""
        p = self.vehicle.pose
        return Pose(p.x + dist_m * float(np.cos(p.heading)), p.y + dist_m * float(np.sin(p.heading)), p.heading)

    def _intervene(self) -> None:
        """Off the road: put the car back on the lane centre, as a safety driver would."""
        o = self._ahead(self.vehicle.params.wheelbase_m / 2)
        x, y, heading = self.course.nearest_lane_pose(o.x, o.y)
        half = self.vehicle.params.wheelbase_m / 2
        self.vehicle.pose = Pose(x - half * float(np.cos(heading)), y - half * float(np.sin(heading)), heading)
        self.vehicle.wheel_deg = 0.0

    def report(self) -> dict:
        return self.score.report(self.course, self.vehicle.odometer_m, self.t)


def run_inprocess(sim: Simulator, driver, progress=None) -> dict:
    """Lockstep with a Driver in this process, through the same JSON/JPEG messages."""
    while not sim.done:
        msg = sim.observe()
        t0 = time.perf_counter()
        perception, cmd = driver.step(decode_telemetry(msg))
        sim.advance(cmd.steering, cmd.throttle, (time.perf_counter() - t0) * 1e3)
        if progress is not None:
            progress(sim, cmd, perception)
    return sim.report()


async def _client(sim: Simulator, url: str, lockstep: bool, progress) -> dict:
    from websockets.asyncio.client import connect
    async with connect(url, max_size=None) as ws:
        command = (0.0, 0.0)
        period = 1.0 / sim.config.fps
        next_t = time.perf_counter()
        sent: dict[int, float] = {}
        while not sim.done:
            msg = sim.observe()
            t_send = time.perf_counter()
            await ws.send(msg)
            latency = None
            if lockstep:
                reply = await ws.recv()
                latency = (time.perf_counter() - t_send) * 1e3
                command = _decode(reply, command)
            else:
                sent[sim.frame] = t_send
                # take every answer that has arrived; act on the newest
                while True:
                    try:
                        reply = await asyncio.wait_for(ws.recv(), timeout=max(0.0, next_t + period - time.perf_counter()))
                    except asyncio.TimeoutError:
                        break
                    command = _decode(reply, command)
                    if sent:
                        latency = (time.perf_counter() - sent.pop(min(sent))) * 1e3
                next_t += period
            sim.advance(*command, latency)
            if progress is not None:  # a remote driver's state and perception are not on the wire
                progress(sim, Command(command[0], command[1], "remote"), None)
    return sim.report()


def _decode(reply, previous: tuple[float, float]) -> tuple[float, float]:
    try:
        return decode_command(reply)
    except ProtocolError as e:
        log.warning("ignored answer: %s", e)
        return previous


def run_client(sim: Simulator, url: str = "ws://127.0.0.1:4567", lockstep: bool = True, progress=None) -> dict:
    return asyncio.run(_client(sim, url, lockstep, progress))
