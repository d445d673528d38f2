"""What the live monitor shows, kept apart from the driver's time.

The drive loop calls `Monitor.publish` once per driven frame: it keeps a reference to the
frame's Perception and Command and appends a few numbers to a ring (no copy, no drawing, no
encoding: the same cost whether or not anyone watches). Viewers (signlane/drive/web.py) take
the newest snapshot when they are ready for one and encode the topic they asked for on the
monitor's own thread: a slow viewer skips frames, it never queues them, and two viewers of the
same topic share one encoding.
"""
from __future__ import annotations

import asyncio
import json
import os
import threading
import time
from collections import deque
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import cv2
import numpy as np

from signlane.config import CameraConfig
from signlane.types import Command, Perception

# topic -> what it shows (the page's menu); overlays (lanes, boxes) are drawn by the page on the
# topics in the camera's own geometry
TOPICS = {
    "rgb": "camera",
    "mask": "lane method's mask (the drivable road on a kerbed road, lane paint on a painted one)",
    "drivable": "drivable road surface (road-edges' scan, or a road model's drivable head)",
    "birdseye": "bird's-eye view of the road ahead",
    "colours": "sign colour masks (red, blue)",
    "canny": "edges (Canny)",
}
ALIGNED = {"rgb", "mask", "drivable", "canny"}  # in the camera's pixels: the page draws lanes and boxes over them
JPEG_QUALITY = 70
MAX_VIEWER_FPS = 15.0  # a person watching needs no more; each frame encoded is CPU the driver could use
STREAM_WIDTH = 320  # streamed frames are at most this wide (a quarter of VIA's pixels to encode and decode);
# the page draws the overlays from the full frame's numbers, so lanes and boxes stay sharp
MONITOR_NICE = 10  # the encoding thread yields the CPU to the driver's threads (Linux: per-thread niceness)
HISTORY = 3000  # samples kept for the plots (100 s at 30 frames/s)


@dataclass(frozen=True)
class Snapshot:
    seq: int
    wall: float
    perception: Perception
    command: Command
    speed_mps: float
    latency_ms: float | None
    confirmed: tuple[str, ...]
    source: str


@dataclass
class _Cache:
    seq: int = -1
    frames: dict[str, bytes] = field(default_factory=dict)


class Monitor:
    """The drive loop's window for people: thread-safe `publish`, and snapshots, topics and
    plot samples for the web viewers."""

    def __init__(self, camera: CameraConfig | None = None, history: int = HISTORY):
        self.camera = camera or CameraConfig()
        self.latest: Snapshot | None = None
        self.samples: deque[tuple] = deque(maxlen=history)  # (index, t, steering, throttle, speed, latency, perceive)
        self.viewers = 0
        self.encoded = 0  # frames encoded for viewers (none while nobody watches)
        self._seq = 0
        self._walls: deque[float] = deque(maxlen=120)
        self._cache = _Cache()
        self._lock = threading.Lock()
        self._birdseye: dict[tuple[int, int], object] = {}
        self._waiters: list[tuple[asyncio.AbstractEventLoop, asyncio.Event]] = []
        # one low-priority thread: viewers never take more than one core from the driver, however
        # many there are, and only what the driver leaves
        self.pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="monitor", initializer=_lower_priority)

    def publish(self, perception: Perception, command: Command, speed_mps: float, latency_ms: float | None = None,
                confirmed=(), source: str = "") -> None:
        """One driven frame (any thread). Cheap on purpose: references and numbers only."""
        now = time.monotonic()
        self._seq += 1
        timing = perception.timing_ms
        perceive = sum(v for k, v in timing.items() if "_" not in k)  # the stages, not their parts
        self.samples.append((self._seq, now, float(command.steering), float(command.throttle), float(speed_mps),
                             latency_ms, perceive))
        self._walls.append(now)
        self.latest = Snapshot(self._seq, now, perception, command, float(speed_mps), latency_ms,
                               tuple(getattr(d, "label", str(d)) for d in confirmed), source)
        for loop, event in list(self._waiters):  # wake the viewers (none attached: nothing to do)
            loop.call_soon_threadsafe(event.set)

    def watch(self, loop: asyncio.AbstractEventLoop, event: asyncio.Event) -> None:
        """A viewer's event, set (on its loop) whenever a frame is published."""
        self._waiters.append((loop, event))
        self.viewers += 1

    def unwatch(self, event: asyncio.Event) -> None:
        self._waiters = [w for w in self._waiters if w[1] is not event]
        self.viewers -= 1

    def message(self, snap: Snapshot, topic: str, after: int, width: int = STREAM_WIDTH) -> tuple[str, bytes, int]:
        """(state JSON text, topic JPEG at most `width` wide, newest sample index) for a viewer:
        all the work of one streamed frame, done on the monitor thread rather than the server's
        event loop."""
        data = self.jpeg(snap, topic, width)
        state = self.state(snap, after)
        state.update(topic=topic, aligned=topic in ALIGNED)
        return json.dumps(state), data, (state["samples"][-1][0] if state["samples"] else after)

    def fps(self) -> float:
        w = list(self._walls)
        if len(w) < 2 or time.monotonic() - w[-1] > 2.0:
            return 0.0
        return (len(w) - 1) / max(w[-1] - w[0], 1e-9)

    def state(self, snap: Snapshot | None, after: int = 0) -> dict:
        """The page's numbers: the snapshot's lane, signs and command, plus plot samples newer
        than `after` (at most 600)."""
        out: dict = {"type": "state", "fps": round(self.fps(), 1), "viewers": self.viewers, "encoded": self.encoded,
                     "samples": [[i, round(t, 3), round(s, 4), round(th, 4), round(v, 3),
                                  None if lat is None else round(lat, 2), round(pm, 2)]
                                 for i, t, s, th, v, lat, pm in list(self.samples) if i > after][-600:]}
        if snap is None:
            return {**out, "seq": 0}
        p, c = snap.perception, snap.command
        h, w = p.frame.image_bgr.shape[:2]
        lane = p.lane

        def pl(a):
            return [] if a is None else [[round(float(x), 1), round(float(y), 1)] for x, y in a]
        return {**out, "seq": snap.seq, "source": snap.source, "width": int(w), "height": int(h),
                "t": round(float(p.frame.t), 3), "speed": round(snap.speed_mps, 3),
                "latency_ms": None if snap.latency_ms is None else round(snap.latency_ms, 2),
                "command": {"steering": round(float(c.steering), 4), "throttle": round(float(c.throttle), 4),
                            "state": c.state},
                "lane": {"method": lane.method, "found": bool(lane.found), "basis": lane.basis,
                         "offset": round(float(lane.offset), 4), "heading": round(float(lane.heading), 5),
                         "left": pl(lane.left), "right": pl(lane.right)},
                "signs": [{"label": s.label, "score": round(float(s.score), 3), "box": [int(v) for v in s.box]}
                          for s in p.signs],
                "confirmed": list(snap.confirmed),
                "timing_ms": {k: round(v, 2) for k, v in p.timing_ms.items()}}

    def jpeg(self, snap: Snapshot, topic: str, width: int = 0) -> bytes:
        """The snapshot's topic as JPEG bytes, at most `width` wide (0: as it is), on the monitor
        thread; each (frame, topic, width) encoded once, however many viewers ask."""
        key = f"{topic}@{width}"
        with self._lock:
            if self._cache.seq == snap.seq and key in self._cache.frames:
                return self._cache.frames[key]
        image = self.topic_image(snap, topic)
        if 0 < width < image.shape[1]:
            image = cv2.resize(image, (width, max(1, round(image.shape[0] * width / image.shape[1]))),
                               interpolation=cv2.INTER_AREA)
        data = encode_jpeg(image)
        with self._lock:
            if self._cache.seq != snap.seq:
                self._cache = _Cache(snap.seq)
            self._cache.frames[key] = data
            self.encoded += 1
        return data

    def topic_image(self, snap: Snapshot, topic: str) -> np.ndarray:
        """uint8 BGR (or grey) image of a topic; ValueError for an unknown one."""
        image = snap.perception.frame.image_bgr
        h, w = image.shape[:2]
        if topic == "rgb":
            return image
        if topic in ("mask", "drivable"):
            lane = snap.perception.lane.with_masks()  # (made here, for the viewer: the car never waits for them)
            mask = lane.debug_mask if topic == "mask" else lane.drivable_mask
            if mask is None:  # (a lane method with no road output: nothing to show)
                return np.zeros((h, w), np.uint8)
            mask = (mask > 0).astype(np.uint8) * 255
            return cv2.resize(mask, (w, h), interpolation=cv2.INTER_NEAREST) if mask.shape[:2] != (h, w) else mask
        if topic == "birdseye":
            bev = self._birdseye.get((w, h))
            if bev is None:
                bev = self._birdseye[(w, h)] = self.camera.camera(w, h).default_birdseye(0.5)
            return bev.warp(image)
        if topic == "colours":
            from signlane.signs.proposals import color_masks
            m = color_masks(image)
            out = np.zeros_like(image)
            out[m["red"] > 0] = (0, 0, 255)
            out[m["blue"] > 0] = (255, 80, 0)
            return out
        if topic == "canny":
            return cv2.Canny(cv2.cvtColor(image, cv2.COLOR_BGR2GRAY), 60, 150)
        raise ValueError(f"unknown topic {topic!r} (topics: {', '.join(TOPICS)})")

    def close(self) -> None:
        self.pool.shutdown(wait=False, cancel_futures=True)


def _lower_priority() -> None:
    try:
        os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), MONITOR_NICE)  # this thread only, on Linux
    except (AttributeError, OSError):
        pass  # elsewhere: the thread keeps the process's priority


def encode_jpeg(image: np.ndarray, quality: int = JPEG_QUALITY) -> bytes:
    ok, buf = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, quality])
    if not ok:
        raise ValueError(f"cannot encode a {image.shape} image as JPEG")
    return buf.tobytes()
