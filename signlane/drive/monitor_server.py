"""The monitor on its own, for `signlane run` (no simulator socket): the same page and viewer
stream as the drive server's (signlane/drive/web.py), on a background thread with its own event
loop, so the drive loop's thread only ever calls Monitor.publish."""
from __future__ import annotations

import asyncio
import logging
import threading

from websockets.asyncio.server import serve as ws_serve

from signlane.drive.monitor import Monitor
from signlane.drive.web import WebMonitor

log = logging.getLogger("signlane.monitor")
ws_log = logging.getLogger("signlane.monitor.websockets")
ws_log.setLevel(logging.WARNING)


class MonitorServer:
    """`with MonitorServer(monitor, host, port) as srv:` serves http://host:srv.port/."""

    def __init__(self, monitor: Monitor, host: str = "127.0.0.1", port: int = 4567, allow_control: bool = False):
        self.web = WebMonitor(monitor, allow_control)
        self.host, self.port = host, port
        self._ready = threading.Event()
        self._error: BaseException | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._stop: asyncio.Event | None = None
        self._thread = threading.Thread(target=self._main, name="monitor-server", daemon=True)

    @property
    def url(self) -> str:
        return f"http://{self.host}:{self.port}/"

    async def _handle(self, ws) -> None:
        if self.web.is_viewer(ws.request.path):
            await self.web.viewer(ws)
        else:
            await ws.close(1008, "signlane run drives a camera: no simulator socket here (the monitor is at /)")

    def _main(self) -> None:
        async def main() -> None:
            self._loop, self._stop = asyncio.get_running_loop(), asyncio.Event()
            async with ws_serve(self._handle, self.host, self.port, logger=ws_log,
                                process_request=self.web.process_request) as server:
                self.port = server.sockets[0].getsockname()[1]
                self._ready.set()
                await self._stop.wait()
        try:
            asyncio.run(main())
        except BaseException as e:  # reported to the thread that called start()
            self._error = e
        finally:
            self._ready.set()

    def start(self) -> "MonitorServer":
        self._thread.start()
        self._ready.wait(30)
        if self._error is not None:
            raise self._error
        log.info("monitor: %s", self.url)
        return self

    def close(self) -> None:
        if self._loop is not None and self._thread.is_alive():
            self._loop.call_soon_threadsafe(self._stop.set)
        self._thread.join(timeout=10)

    def __enter__(self) -> "MonitorServer":
        return self.start()

    def __exit__(self, *exc) -> None:
        self.close()
