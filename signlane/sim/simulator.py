"""signlane's local VIA-compatible simulator: the world renderer plus VIA's car.

`Simulator` renders the camera view at the car's pose, sends it as VIA's telemetry bytes (N4
strings, mph, a JPEG of quality 75; the image one frame behind the numbers, as VIA's is),
applies replies as VIA's car does (signlane/sim/vehicle.py) and referees the drive
(signlane/sim/course.py). Ways to run it, each calling `progress(sim, command, perception)`
after every frame (perception None when remote):
- `run_inprocess(sim, driver)`: lockstep with a Driver object in the same process (tests, demo,
  the closed-loop benchmark): the bytes of a lockstep client run (below) both ways, so it drives
  as `sim --with-driver --lockstep` does, without the socket.
- `run_client(sim, url, lockstep)`: as a WebSocket client of a drive server, sending binary
  frames as VIA does. Real time (lockstep False) is VIA's behaviour: exactly VIA's bytes, frames
  paced at `fps` (or as fast as they can be made), never waiting for a reply, each reply applied
  to the car when it arrives (the newest wins). Lockstep waits for each reply (deterministic),
  which VIA never does, and adds the `"time"` key, which VIA never sends: a server has no other
  way to keep simulated time.
"""
from __future__ import annotations

import asyncio
import logging
import math
import time
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from signlane.camera import VIA_CAMERA_FORWARD_M, via_camera
from signlane.sim.course import CourseTracker
from signlane.sim.protocol import (ProtocolError, decode_command, decode_telemetry, encode_command, encode_jpeg,
                                   encode_telemetry)
from signlane.sim.score import Score
from signlane.sim.vehicle import Vehicle, VehicleParams
from signlane.types import Command
from signlane.world.effects import Effects
from signlane.world.render import Renderer
from signlane.world.route import Pose
from signlane.world.scene import build_scene
from signlane.world.track import Track

log = logging.getLogger(__name__)


MAX_WALL_STEP_S = 0.1  # a stalled frame (GC, a busy machine) advances the car at most this much


@dataclass(frozen=True)
class SimConfig:
    width: int = 640
    height: int = 480
    fps: float = 30.0  # frames per second; 0 = uncapped (each frame's time step is the wall time)
    jpeg_quality: int = 75  # VIA's
    effects: str = "clean"
    looks_seed: int = 0
    random_looks: bool = False
    laps: int = 1
    max_seconds: float = 600.0
    vehicle: VehicleParams = field(default_factory=VehicleParams)
    send_time: bool = False  # add the "time" key (simulated seconds): signlane's, VIA sends none
    decimal: str = "."  # the decimal mark of the numbers sent: "," as from a comma-decimal locale
    image_lag_frames: int = 1  # VIA's message carries the previous frame's image with current numbers
    # VIA's camera sits 0.1 m ahead of the car's origin, which is midway between the axles; the
    # car's pose is its rear axle's
    camera_forward_m: float = VIA_CAMERA_FORWARD_M

    def __post_init__(self) -> None:
        if not (math.isfinite(self.fps) and self.fps >= 0):
            raise ValueError(f"fps must be a positive number or 0 (uncapped), not {self.fps}")
        if self.decimal not in (".", ","):
            raise ValueError(f"decimal must be '.' or ',', not {self.decimal!r}")
        if self.image_lag_frames < 0:
            raise ValueError(f"image_lag_frames must be >= 0, not {self.image_lag_frames}")


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
        self.last_image: np.ndarray | None = None  # the image of the last message sent
        self._effects = Effects.named(c.effects)
        self._images: deque[tuple[np.ndarray, bytes]] = deque(maxlen=max(int(c.image_lag_frames), 0) + 1)
        self._wall = time.perf_counter()

    @property
    def done(self) -> bool:
        return self.course.laps >= self.config.laps or self.t >= self.config.max_seconds

    def observe(self, send_time: bool | None = None) -> bytes:
        """Render the frame at the current pose; the telemetry message bytes (with the image of
        `image_lag_frames` frames ago). `send_time` overrides the config's."""
        v, c = self.vehicle, self.config
        rng = np.random.default_rng([c.looks_seed, self.frame])
        image = self.renderer.render(self._ahead(c.camera_forward_m + v.params.wheelbase_m / 2),
                                     self.camera, self._effects, rng).image
        self._images.append((image, encode_jpeg(image, c.jpeg_quality)))
        self.last_image, jpeg = self._images[0]  # the oldest kept: the current one until the lag fills
        with_time = c.send_time if send_time is None else send_time
        return encode_telemetry(v.wheel_deg, v.pedal, v.speed, jpeg, self.t if with_time else None, c.decimal)

    def advance(self, command: tuple[float, float] | None, latency_ms: float | None = None,
                dt: float | None = None) -> None:
        """One frame: a reply (steering, throttle) that arrived in it, or None for no new reply
        (the car keeps its last steering and pedal); then the car moves and is refereed.

        dt: the frame's simulated seconds; by default 1 / fps, or with fps 0 the wall time since
        the previous frame (at most 0.1 s)."""
        now = time.perf_counter()
        if dt is None:
            fps = self.config.fps
            dt = 1.0 / fps if fps > 0 else min(now - self._wall, MAX_WALL_STEP_S)
        self._wall = now
        if command is not None:
            self.vehicle.command(*command)
        self.vehicle.step(dt)
        self.t += dt
        self.frame += 1
        p = self._ahead(self.vehicle.params.wheelbase_m / 2)  # the car's origin, as VIA's referee would see it
        self.path.append((p.x, p.y))
        cte = self.course.update(self.t, p.x, p.y, p.heading, self.vehicle.speed)
        if self.score.frame(self.t, cte, self.vehicle.speed, latency_ms, (p.x, p.y)):
            self._intervene()

    def _ahead(self, dist_m: float) -> Pose:
        """The point dist_m ahead of the rear axle (the car's origin, its camera)."""
        p = self.vehicle.pose
        return Pose(p.x + dist_m * float(np.cos(p.heading)), p.y + dist_m * float(np.sin(p.heading)), p.heading)

    def _intervene(self) -> None:
        """Off the road: put the car back on the lane centre (turned round at a dead end), as a safety driver would."""
        o = self._ahead(self.vehicle.params.wheelbase_m / 2)
        x, y, heading = self.course.put_back_pose(o.x, o.y)
        half = self.vehicle.params.wheelbase_m / 2
        self.vehicle.pose = Pose(x - half * float(np.cos(heading)), y - half * float(np.sin(heading)), heading)
        self.vehicle.wheel_deg = 0.0

    def report(self) -> dict:
        return self.score.report(self.course, self.vehicle.odometer_m, self.t)


def run_inprocess(sim: Simulator, driver, progress=None) -> dict:
    """Lockstep with a Driver in this process, through the exact bytes a lockstep drive server
    sees and sends: the frame with its `"time"` key (4 decimals, as on the wire) and the answer
    as the server encodes it and VIA reads it. So the same track drives the same way here and
    through `sim --with-driver --lockstep` (the simulated time unrounded, or the steering
    unclipped, once made them two drives that parted after a minute)."""
    while not sim.done:
        msg = sim.observe(send_time=True)
        t0 = time.perf_counter()
        perception, cmd = driver.step(decode_telemetry(msg))
        reply = decode_command(encode_command(cmd.steering, cmd.throttle))
        sim.advance(reply, (time.perf_counter() - t0) * 1e3)
        if progress is not None:
            progress(sim, cmd, perception)
    return sim.report()


async def _lockstep(sim: Simulator, ws, progress) -> None:
    command = (0.0, 0.0)
    while not sim.done:
        t_send = time.perf_counter()
        await ws.send(sim.observe(send_time=True))  # bytes: a binary frame, as VIA sends
        reply = await ws.recv()
        latency = (time.perf_counter() - t_send) * 1e3
        new = _decode(reply)
        command = new or command
        sim.advance(new, latency)
        if progress is not None:  # a remote driver's state and perception are not on the wire
            progress(sim, Command(command[0], command[1], "remote"), None)


async def _realtime(sim: Simulator, ws, progress) -> None:
    """VIA's way: send each frame and go on; replies are read as they come, the newest wins."""
    sent: deque[float] = deque()  # send times of frames not yet answered (for latency)
    latency: list[float] = []  # what arrived during the current frame
    arrived: list[tuple[float, float]] = []  # the newest reply not yet handed to the car

    async def read() -> None:
        async for reply in ws:
            if sent:
                latency.append((time.perf_counter() - sent.popleft()) * 1e3)
            new = _decode(reply)
            if new is not None:
                arrived[:] = [new]

    reader = asyncio.create_task(read())
    fps = sim.config.fps
    period = 1.0 / fps if fps > 0 else 0.0
    next_t = last = time.perf_counter()
    command = (0.0, 0.0)
    try:
        while not sim.done:  # a closed connection ends it: ws.send raises ConnectionClosed
            sent.append(time.perf_counter())
            await ws.send(sim.observe())
            next_t += period
            await asyncio.sleep(max(0.0, next_t - time.perf_counter()))  # 0: just let replies in
            now = time.perf_counter()
            if now > next_t + period:
                next_t = now  # fell behind: go on from here rather than rush to catch up
            # the physics of the time that just passed, on the command the car had then (the
            # simulated clock follows the wall clock, as Unity's does) ...
            sim.advance(None, latency[-1] if latency else None, dt=min(now - last, MAX_WALL_STEP_S))
            last = now
            latency.clear()
            if arrived:  # ... and a reply that came in meanwhile acts from the car's next physics tick
                command = arrived.pop()
                sim.vehicle.command(*command)
            if progress is not None:
                progress(sim, Command(command[0], command[1], "remote"), None)
    finally:
        reader.cancel()
        await asyncio.gather(reader, return_exceptions=True)


async def _client(sim: Simulator, url: str, lockstep: bool, progress, wait_s: float) -> dict:
    from websockets.asyncio.client import connect
    deadline = time.monotonic() + wait_s
    while True:  # a server started just before (`signlane drive & signlane sim`) may not listen yet
        try:
            ws = await connect(url, max_size=None)
            break
        except ConnectionRefusedError:
            if time.monotonic() >= deadline:
                raise
            await asyncio.sleep(0.25)
    async with ws:
        await (_lockstep if lockstep else _realtime)(sim, ws, progress)
    return sim.report()


def _decode(reply) -> tuple[float, float] | None:
    """A reply as VIA reads it, or None (logged) for one VIA would ignore."""
    try:
        return decode_command(reply)
    except ProtocolError as e:
        log.warning("ignored reply: %s", e)
        return None


def run_client(sim: Simulator, url: str = "ws://127.0.0.1:4567", lockstep: bool = True, progress=None,
               wait_s: float = 10.0) -> dict:
    """Drive `sim` as a WebSocket client of the drive server at `url` (see the module docstring:
    real time is VIA's behaviour; lockstep waits for replies and adds the `"time"` key). A
    refused connection is tried again for up to wait_s seconds (the server may be starting)."""
    return asyncio.run(_client(sim, url, lockstep, progress, wait_s))
