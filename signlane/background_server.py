"""An asyncio server on a thread of its own, for callers that are not async: the drive server
in tests and `signlane sim --with-driver`, the monitor of `signlane run`. start() returns once it
listens (or raises what stopped it from listening); close() stops its loop and joins the thread."""
from __future__ import annotations

import asyncio
import threading


class BackgroundServer:
    def __init__(self, name: str, start_timeout_s: float = 60.0, join_timeout_s: float = 30.0):
        self.port: int | None = None
        self.start_timeout_s, self.join_timeout_s = start_timeout_s, join_timeout_s
        self._ready = threading.Event()
        self._error: BaseException | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._stop: asyncio.Event | None = None
        self._thread = threading.Thread(target=self._main, name=name, daemon=True)

    async def serve_until(self, stop: asyncio.Event) -> None:
        """Serve until `stop` is set; call self.listening(port) once the socket is bound."""
        raise NotImplementedError

    def listening(self, port: int) -> None:
        self.port = port
        self._ready.set()

    def _main(self) -> None:
        async def main() -> None:
            self._loop, self._stop = asyncio.get_running_loop(), asyncio.Event()
            await self.serve_until(self._stop)
        try:
            asyncio.run(main())
        except BaseException as e:  # reported to the thread that called start()
            self._error = e
        finally:
            self._ready.set()

    def start(self):
        self._thread.start()
        if not self._ready.wait(self.start_timeout_s):
            raise TimeoutError(f"{self._thread.name} did not start within {self.start_timeout_s:.0f} s")
        if self._error is not None:
            raise self._error
        return self

    def close(self) -> None:
        if self._loop is not None and self._thread.is_alive():
            self._loop.call_soon_threadsafe(self._stop.set)
        self._thread.join(timeout=self.join_timeout_s)

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc) -> None:
        self.close()
