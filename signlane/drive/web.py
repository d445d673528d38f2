"""The live monitor on the drive server's own host and port, as VIA's Visualizer is: plain HTTP
GETs get the page (`/`, also VIA's `/web/index.html`) and read-only JSON/JPEG endpoints; a
WebSocket to `/monitor` streams one topic; every other WebSocket is the simulator's.

Streaming is pull-based: the server sends a frame's state (text) and JPEG (binary), then waits
for the page's ack before it takes the newest snapshot again, so a slow viewer sees fewer frames
and nothing queues. Nothing here writes to disk or changes a setting unless the server was
started with allow_control (then a viewer may ask to save the current frame and its state).
"""
from __future__ import annotations

import asyncio
import http
import ipaddress
import json
import logging
import math
from pathlib import Path
from urllib.parse import parse_qs, urlsplit

from websockets.datastructures import Headers
from websockets.exceptions import ConnectionClosed
from websockets.http11 import Request, Response

from signlane.drive.monitor import MAX_VIEWER_FPS, TOPICS, Monitor

log = logging.getLogger("signlane.monitor")
PAGE_DIR = Path(__file__).parent / "web"
STATIC = {"/": ("monitor.html", "text/html; charset=utf-8"),
          "/index.html": ("monitor.html", "text/html; charset=utf-8"),
          "/web/index.html": ("monitor.html", "text/html; charset=utf-8"),  # where VIA's Visualizer lives
          "/monitor.js": ("monitor.js", "text/javascript; charset=utf-8")}
VIEWER_PATH = "/monitor"


def is_loopback(host: str) -> bool:
    """True for an address only this machine reaches ("" and 0.0.0.0 are every interface)."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def warn_if_exposed(host: str, what: str) -> None:
    if not is_loopback(host):
        log.warning("%s listens on %s: anyone who can reach this address sees the camera and, over the drive "
                    "socket, can steer the car; use 127.0.0.1 unless you mean it", what, host)


def _response(status: int, body: bytes, ctype: str) -> Response:
    headers = Headers([("Content-Type", ctype), ("Content-Length", str(len(body))), ("Cache-Control", "no-store"),
                       ("Connection", "close")])
    return Response(status, http.HTTPStatus(status).phrase, headers, body)


def _text(status: int, text: str) -> Response:
    return _response(status, (text + "\n").encode(), "text/plain; charset=utf-8")


class WebMonitor:
    """The HTTP routes and the viewer handler of one Monitor (use `process_request` as the
    websockets server's hook; call `viewer(ws)` for connections to VIEWER_PATH)."""

    def __init__(self, monitor: Monitor, allow_control: bool = False, save_dir: Path | None = None):
        self.monitor, self.allow_control = monitor, allow_control
        self.save_dir = save_dir or Path("monitor_snapshots")

    @staticmethod
    def is_viewer(path: str) -> bool:
        return urlsplit(path).path == VIEWER_PATH

    async def process_request(self, connection, request: Request) -> Response | None:
        if "websocket" in request.headers.get("Upgrade", "").lower():
            return None  # a WebSocket: the simulator's or a viewer's; the handler tells them apart
        url = urlsplit(request.path)
        if url.path in STATIC:
            name, ctype = STATIC[url.path]
            return _response(200, (PAGE_DIR / name).read_bytes(), ctype)
        if url.path == "/api/topics":
            return _response(200, json.dumps(TOPICS).encode(), "application/json")
        if url.path == "/api/state":
            state = self.monitor.state(self.monitor.latest)
            return _response(200, json.dumps(state).encode(), "application/json")
        if url.path == "/api/frame.jpg":
            topic = parse_qs(url.query).get("topic", ["rgb"])[0]
            if topic not in TOPICS:
                return _text(404, f"unknown topic {topic!r} (topics: {', '.join(TOPICS)})")
            snap = self.monitor.latest
            if snap is None:
                return _text(503, "no frame driven yet")
            data = await asyncio.get_running_loop().run_in_executor(self.monitor.pool, self.monitor.jpeg, snap, topic)
            return _response(200, data, "image/jpeg")
        return _text(404, f"not found: {url.path} (the monitor is at /)")

    async def viewer(self, ws) -> None:
        """Stream to one page until it leaves: state then JPEG per frame, the next frame only
        after the page's ack."""
        m = self.monitor
        loop = asyncio.get_running_loop()
        want = {"topic": "rgb", "changed": True}
        ready = asyncio.Event()
        ready.set()

        async def read() -> None:
            try:
                await _read()
            finally:
                ready.set()  # the page is gone: wake the sender so it ends too

        async def _read() -> None:
            async for message in ws:
                try:
                    msg = json.loads(message)
                    if not isinstance(msg, dict):
                        raise ValueError
                except ValueError:
                    await ws.send(json.dumps({"type": "error", "error": "messages are JSON objects"}))
                    continue
                if "topic" in msg:
                    if msg["topic"] in TOPICS:
                        want.update(topic=msg["topic"], changed=True)
                    else:
                        await ws.send(json.dumps({"type": "error", "error": f"unknown topic {msg['topic']!r}"}))
                if msg.get("save"):
                    await ws.send(json.dumps(await self._save()))
                if "ack" in msg or "topic" in msg:
                    ready.set()

        fresh = asyncio.Event()  # set by Monitor.publish whenever a frame is driven
        m.watch(loop, fresh)
        reader = asyncio.create_task(read())
        last_seq = last_sample = 0
        next_at = 0.0
        try:
            while not reader.done():
                await ready.wait()  # the page has drawn the last frame (or changed topic)
                fresh.clear()  # before looking: a frame published from here on wakes the wait below
                snap = m.latest
                if snap is None or (snap.seq == last_seq and not want["changed"]):
                    waiter = asyncio.ensure_future(fresh.wait())
                    await asyncio.wait([waiter, reader], return_when=asyncio.FIRST_COMPLETED)
                    waiter.cancel()
                    continue
                wait = next_at - loop.time()
                if wait > 0 and not want["changed"]:
                    await asyncio.sleep(wait)  # at most MAX_VIEWER_FPS: the newest frame after the pause
                    continue
                ready.clear()
                topic, want["changed"] = want["topic"], False
                # the next slot on a clock all viewers share: viewers of one topic take the same
                # newest frame at the same moment, and the monitor encodes it once for them all
                next_at = (math.floor(loop.time() * MAX_VIEWER_FPS) + 1) / MAX_VIEWER_FPS
                text, data, last_sample = await loop.run_in_executor(m.pool, m.message, snap, topic, last_sample)
                await ws.send(text)
                await ws.send(data)
                last_seq = snap.seq
        except ConnectionClosed:
            pass
        finally:
            m.unwatch(fresh)
            reader.cancel()
            await asyncio.gather(reader, return_exceptions=True)

    async def _save(self) -> dict:
        if not self.allow_control:
            return {"type": "error", "error": "control is off: the server was not started with --allow-control"}
        snap = self.monitor.latest
        if snap is None:
            return {"type": "error", "error": "no frame driven yet"}
        from signlane.fileio import atomic_write_json
        from signlane.draw import write_image
        stem = self.save_dir / f"frame_{snap.seq:06d}"
        loop = asyncio.get_running_loop()
        await loop.run_in_executor(self.monitor.pool, write_image, stem.with_suffix(".png"),
                                   snap.perception.frame.image_bgr)
        await loop.run_in_executor(self.monitor.pool, atomic_write_json, stem.with_suffix(".json"),
                                   self.monitor.state(snap, 1 << 62))
        return {"type": "saved", "path": str(stem.with_suffix(".png"))}
