"""The monitor on its own, for `signlane run` (no simulator socket): the same page and viewer
stream as the drive server's (signlane/drive/web.py), on a background thread with its own event
loop, so the drive loop's thread only ever calls Monitor.publish."""
from __future__ import annotations

import asyncio
import logging

from websockets.asyncio.server import serve as ws_serve

from signlane.background_server import BackgroundServer
from signlane.drive.monitor import Monitor
from signlane.drive.web import WebMonitor

log = logging.getLogger("signlane.monitor")
ws_log = logging.getLogger("signlane.monitor.websockets")
ws_log.setLevel(logging.WARNING)


class MonitorServer(BackgroundServer):
    """`with MonitorServer(monitor, host, port) as srv:` serves http://host:srv.port/."""

    def __init__(self, monitor: Monitor, host: str = "127.0.0.1", port: int = 4567, allow_control: bool = False):
        super().__init__("monitor-server", start_timeout_s=30.0, join_timeout_s=10.0)
        self.web = WebMonitor(monitor, allow_control)
        self.host, self.port = host, port

    @property
    def url(self) -> str:
        return f"http://{self.host}:{self.port}/"

    async def _handle(self, ws) -> None:
        if self.web.is_viewer(ws.request.path):
            await self.web.viewer(ws)
        else:
            await ws.close(1008, "signlane run drives a camera: no simulator socket here (the monitor is at /)")

    async def serve_until(self, stop: asyncio.Event) -> None:
        async with ws_serve(self._handle, self.host, self.port, logger=ws_log,
                            process_request=self.web.process_request) as server:
            self.listening(server.sockets[0].getsockname()[1])
            log.info("monitor: %s", self.url)
            await stop.wait()
