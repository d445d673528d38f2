"""The drive server: the VIA simulator (or `signlane sim`) connects, sends frames, gets commands.

VIA sends each frame as a binary WebSocket message holding UTF-8 JSON (signlane/sim/protocol.py);
text frames are accepted too. Each connection gets its own Driver. For every frame, binary or
text, the server answers one command, as a text frame of plain-number JSON:
  - driver idle: decode + Driver.step run on a worker thread (the event loop keeps serving other
    frames and clients), and the new command is the answer;
  - driver busy with an earlier frame: the frame is answered at once with the connection's latest
    command and not decoded. The simulator never waits for answers, so queueing frames would
    only make the car act on ever older images; skipping keeps perception on the newest frame and
    the backlog at zero. A lockstep client (one frame in flight) never sees a skip.
Bad frames get one (rate-limited) log line and SAFE_COMMAND; nothing a client sends stops the
server. The same port serves the live monitor (signlane/drive/web.py): plain HTTP GETs get its
page, WebSockets to /monitor are viewers; each driven frame is handed to it by reference only. Run it with `signlane drive`, `serve()` inside an event loop, or `DriveServer` in a
background thread (tests, `signlane sim --with-driver`).
"""
from __future__ import annotations

import asyncio
import logging
import os
import signal
import time
from collections import deque
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

from websockets.asyncio.server import ServerConnection
from websockets.asyncio.server import serve as ws_serve
from websockets.exceptions import ConnectionClosed

from signlane.background_server import BackgroundServer
from signlane.config import Config
from signlane.imagecheck import DEFAULT_MAX_PIXELS
from signlane.sim.drive_record import DiskWriter, Recorder, Shower, sent_command
from signlane.sim.drive_stats import ErrorLog, Rates, split_ms, split_summary, split_text
from signlane.sim.driver import Driver, SignStageError
from signlane.sim.protocol import (MAX_MESSAGE_BYTES, SAFE_COMMAND, ProtocolError, Telemetry, decode_telemetry,
                                   encode_command)

log = logging.getLogger("signlane.drive")
# websockets logs every connection at INFO; ours already says who connected and why they left
ws_log = logging.getLogger("signlane.drive.websockets")
ws_log.setLevel(logging.WARNING)

DEFAULT_HOST, DEFAULT_PORT = "127.0.0.1", 4567
# websockets itself refuses (close code 1009) messages over this many times our limit; the ones in
# between reach us and get a safe answer, so a slightly oversized frame does not drop the connection
WS_SIZE_FACTOR = 2


@dataclass(frozen=True)
class ServerOptions:
    host: str = DEFAULT_HOST
    port: int = DEFAULT_PORT  # 0 = any free port (see DriveServer.port)
    max_bytes: int = MAX_MESSAGE_BYTES
    max_pixels: int = DEFAULT_MAX_PIXELS  # larger images (from their header) get the safe answer undecoded
    record: Path | None = None  # driving dataset folder
    show_every: int = 0  # write every N-th driven frame annotated; 0 = never
    show_dir: Path | None = None  # where annotated frames go (default: drive_frames/)
    sync_signs: bool = False  # True: signs in step with every frame (deterministic, lockstep)
    log_every_s: float = 10.0  # rate/latency report period
    web: bool = True  # the live monitor page on the same host and port (signlane/drive/web.py)
    allow_control: bool = False  # let monitor viewers save frames (nothing writes or changes anything without it)


@dataclass
class _Result:
    """What a worker hands back to the event loop for one frame."""

    answer: str
    step_ms: float  # decode + perceive
    error: str = ""
    perception: Any = None
    command: Any = None
    telemetry: Any = None
    cancelled: bool = False  # the connection closed before the frame was driven
    decode_ms: float = 0.0  # of step_ms, the message's: JSON, numbers, base64, JPEG checks and decoding
    teacher: Any = None  # with a pilot: the planner's own command, a recording's label
    steered_by: str = ""  # with a pilot: "student" where it steered, "teacher" where the planner did


class _Server:
    """State shared by all connections of one server; touched on the event loop thread only
    (except `make_driver` and the disk writer, which run on worker threads)."""

    def __init__(self, config: Config, options: ServerOptions, driver_factory: Callable[[], Any] | None):
        self.config, self.options = config, options
        self.make_driver = driver_factory or (lambda: Driver(config, sync_signs=options.sync_signs))
        self.pool = ThreadPoolExecutor(max_workers=max(2, os.cpu_count() or 2), thread_name_prefix="drive-step")
        self.rates, self.errors = Rates(), ErrorLog()
        self.recorder = Recorder(options.record, config) if options.record else None
        self.shower = (Shower(options.show_dir or Path("drive_frames"), options.show_every)
                       if options.show_every > 0 else None)
        self.disk = DiskWriter() if (self.recorder or self.shower) else None
        self.clients = 0
        self.next_id = 1
        # each ended connection's frames and latency split, in order (the last 1000)
        self.finished: deque[dict] = deque(maxlen=1000)
        self.monitor = self.web = None
        if options.web:
            from signlane.drive.monitor import Monitor
            from signlane.drive.web import WebMonitor
            self.monitor = Monitor(config.camera)
            self.web = WebMonitor(self.monitor, options.allow_control)

    async def handle(self, ws: ServerConnection) -> None:
        if self.web is not None and self.web.is_viewer(ws.request.path):
            await self.web.viewer(ws)  # a monitor page, not a car
            return
        cid, self.next_id = self.next_id, self.next_id + 1
        self.clients += 1
        try:
            await _Connection(self, ws, cid).run()
        finally:
            self.clients -= 1

    async def report_loop(self) -> None:
        while True:
            await asyncio.sleep(self.options.log_every_s)
            line = self.rates.report(self.clients)
            if line:
                log.info("%s", line)
            self.errors.flush()  # how often each problem recurred, once its window has passed

    def close(self) -> dict:
        """Finish pending work and writes; the run's totals."""
        self.pool.shutdown(wait=True)
        if self.monitor is not None:
            self.monitor.close()
        if self.disk:
            self.disk.close()
            if self.disk.dropped:
                log.warning("the disk fell behind: %d frame writes dropped", self.disk.dropped)
        if self.recorder:
            self.recorder.close()
        self.rates.report(self.clients)
        return {**self.rates.totals, **self.rates.summary(), "connections": list(self.finished)}


class _Connection:
    def __init__(self, server: _Server, ws: ServerConnection, cid: int):
        self.server, self.ws, self.cid = server, ws, cid
        self.driver = None
        self.latest = SAFE_COMMAND  # answer for frames that arrive while the driver is busy
        self.job: asyncio.Task | None = None
        self.after: asyncio.Future | None = None  # the driver's work once an answer is out (answered())
        self.frames = self.driven = 0
        self.closed = False  # set once the client is gone: work not yet driven is dropped
        self.ms = split_ms()  # this connection's own decode / perceive / answer latencies

    async def run(self) -> None:
        peer = self.ws.remote_address
        log.info("client %d connected from %s", self.cid, f"{peer[0]}:{peer[1]}" if peer else "?")
        loop = asyncio.get_running_loop()
        ended = None  # (how the client left, why): its closing line, with the connection's latency split
        try:
            self.driver = await loop.run_in_executor(self.server.pool, self.server.make_driver)
            async for message in self.ws:
                await self.on_message(message)
            ended = ("disconnected", "")
        except ConnectionClosed as e:  # closed without a close frame, mid-message, too big, not UTF-8
            ended = ("dropped", f" ({why_closed(e, self.server.options.max_bytes * WS_SIZE_FACTOR)})")
        except Exception as e:  # e.g. the driver cannot be built: end this connection, not the server
            log.error("client %d: %s: %s; closing its connection", self.cid, type(e).__name__, e)
            await self.ws.close(1011, "driver error")
        finally:
            self.closed = True
            if self.job is not None:
                await asyncio.gather(self.job, return_exceptions=True)  # never close a driver mid-step
            if self.after is not None:
                await asyncio.gather(self.after, return_exceptions=True)
            if self.driver is not None:
                self.driver.close()
            self.server.errors.flush(who=f"client {self.cid}")
            split = split_summary(self.ms)
            if ended:
                log.info("client %d %s after %d frames%s; %s", self.cid, ended[0], self.frames, ended[1],
                         split_text(split))
            self.server.finished.append({"client": self.cid, "path": self.ws.request.path if self.ws.request else "",
                                         "frames": self.frames, "driven": self.driven, **split})

    async def on_message(self, message: str | bytes) -> None:
        t_recv = time.perf_counter()
        self.frames += 1
        rates = self.server.rates
        rates.frames += 1
        problem = self.precheck(message)
        if problem:
            rates.bad += 1
            self.server.errors.warning(f"{problem}; answered with the safe command", who=f"client {self.cid}")
            await self.send(SAFE_COMMAND, t_recv)
        elif self.job is not None and not self.job.done():
            rates.skipped += 1
            await self.send(self.latest, t_recv)
        else:
            self.job = asyncio.create_task(self.drive(message, t_recv))

    def precheck(self, message: str | bytes) -> str:
        """Problems found without decoding (so even while the driver is busy). Binary frames
        (what VIA sends) and text frames alike: bytes or characters against the limit."""
        if len(message) > self.server.options.max_bytes:
            return f"message of {len(message)} bytes is over the {self.server.options.max_bytes}-byte limit"
        return ""

    async def drive(self, message: str | bytes, t_recv: float) -> None:
        loop = asyncio.get_running_loop()
        await self.after_answer()
        try:
            res = await loop.run_in_executor(self.server.pool, self.work, message)
        except SignStageError as e:  # the car must not drive on without the signs it was asked to obey
            res = _Result(SAFE_COMMAND, 0.0, str(e))
        except Exception as e:  # a driver bug on some frame must not end the connection
            res = _Result(SAFE_COMMAND, 0.0, f"driver failed: {type(e).__name__}: {e}")
        if res.cancelled:
            log.debug("client %d: gone while its frame was decoded; not driven", self.cid)
            return
        rates = self.server.rates
        if res.error:
            rates.bad += 1
            self.server.errors.warning(f"{res.error}; answered with the safe command", who=f"client {self.cid}")
        else:
            rates.processed += 1
            rates.decode_ms.append(res.decode_ms)
            rates.perceive_ms.append(res.step_ms - res.decode_ms)
            self.ms["decode"].append(res.decode_ms)
            self.ms["perceive"].append(res.step_ms - res.decode_ms)
        self.latest = res.answer
        latency = await self.send(res.answer, t_recv)
        answered = getattr(self.driver, "answered", None)
        if answered is not None:
            # the work the driver put off until the answer was out (the sign search of this frame,
            # the lane method's) runs in the gap before the next frame, which waits for it
            self.after = loop.run_in_executor(self.server.pool, answered)
        if not res.error:
            self.keep(res)
            self.driven += 1
            monitor = self.server.monitor
            if monitor is not None and res.perception is not None and res.perception.frame is not None:
                monitor.publish(res.perception, res.command, res.telemetry.speed_mps, latency,
                                getattr(self.driver, "confirmed", ()), f"client {self.cid}")

    async def after_answer(self) -> None:
        """Wait for the driver's work after the last answer; a failure is reported (the next
        frame's step makes the work again, and fails there in turn if it still fails)."""
        after, self.after = self.after, None
        if after is None:
            return
        try:
            await after
        except Exception as e:
            self.server.errors.warning(f"driver failed after its answer: {type(e).__name__}: {e}", who=f"client {self.cid}")

    def work(self, message: str | bytes) -> _Result:
        """Runs on a worker thread: decode, perceive, decide."""
        t0 = time.perf_counter()
        try:
            tel = decode_telemetry(message, self.server.options.max_bytes, self.server.options.max_pixels)
        except ProtocolError as e:
            return _Result(SAFE_COMMAND, (time.perf_counter() - t0) * 1e3, str(e))
        if self.closed:  # nobody is left to answer: spare the CPU the step
            return _Result(SAFE_COMMAND, 0.0, cancelled=True)
        t1 = time.perf_counter()
        perception, cmd = self.driver.step(tel)
        answer = encode_command(cmd.steering, cmd.throttle)
        pilot = getattr(self.driver, "pilot", None)
        teacher = self.driver.planner_command if pilot is not None else None
        steered_by = "" if pilot is None else ("student" if pilot.last is not None else "teacher")
        return _Result(answer, (time.perf_counter() - t0) * 1e3, "", perception, cmd, tel,
                       decode_ms=(t1 - t0) * 1e3, teacher=teacher, steered_by=steered_by)

    async def send(self, answer: str, t_recv: float) -> float | None:
        """Send an answer; its latency in ms since the frame arrived (None if the client is gone)."""
        try:
            await self.ws.send(answer)
        except ConnectionClosed:
            return None  # the reader loop reports the disconnect
        ms = (time.perf_counter() - t_recv) * 1e3
        self.server.rates.answer_ms.append(ms)
        self.ms["answer"].append(ms)
        return ms

    def keep(self, res: _Result) -> None:
        """Hand a driven frame to the disk thread (recording, annotated frames)."""
        s = self.server
        if s.disk is None:
            return
        frame_id = f"c{self.cid}-{self.driven:06d}"
        sent = sent_command(res.answer, res.command.state)
        if s.recorder:  # a pilot's drive is labelled with what the planner would have sent
            extra = {"student": round(float(sent.steering), 4), "steered_by": res.steered_by} if res.teacher else None
            s.disk.submit(lambda: s.recorder.write(frame_id, self.cid, res.telemetry.jpeg, res.telemetry,
                                                   res.perception, sent, res.teacher, extra))
        if s.shower and s.shower.wants(self.driven):
            s.disk.submit(s.shower.write, frame_id, res.telemetry.speed_mps, res.perception, sent)


# close codes the server sends when a client breaks the protocol (websockets closes the connection)
CLOSE_REASONS = {1002: "protocol error", 1007: "a text frame that is not valid UTF-8", 1009: "message too big"}


def why_closed(e: ConnectionClosed, size_limit: int) -> str:
    """How a connection ended, for its log line: the code we closed it with when the client
    broke the protocol, else the client's close frame, or that there was none."""
    sent, rcvd = e.sent, e.rcvd
    if sent is not None and sent.code == 1009:
        return f"message over {size_limit} bytes, closed with 1009"
    if sent is not None and sent.code not in (1000, 1001):
        what = CLOSE_REASONS.get(sent.code, "error")
        return f"{what}{f': {sent.reason}' if sent.reason else ''}, closed with {sent.code}"
    if rcvd is not None:
        return f"code {rcvd.code} {rcvd.reason!r}"
    return "no close frame"


def probe_driver(make_driver: Callable[[], Any]) -> None:
    """Build a driver and drive one grey frame, so what would fail every connection (an unknown
    lane method, a missing model file: models load on the first frame) fails before listening."""
    import numpy as np
    from signlane.onnx_model import ModelError
    driver = make_driver()
    try:
        driver.step(Telemetry(wheel_deg=0.0, pedal=0.0, speed_mps=0.0, image_bgr=np.full((240, 320, 3), 110, np.uint8),
                              time=0.0))
    except (ModelError, ValueError, OSError, SignStageError):
        raise
    except Exception as e:  # a driver bug on a blank frame: worth a line, not a refusal to serve
        log.warning("the driver failed on a blank test frame: %s: %s", type(e).__name__, e)
    finally:
        driver.close()


async def serve(config: Config | None = None, options: ServerOptions | None = None,
                driver_factory: Callable[[], Any] | None = None,
                ready: Callable[[int], None] | None = None, stop: asyncio.Event | None = None) -> dict:
    """Serve until `stop` is set (forever if None); returns the run's totals.

    `ready(port)` is called once listening (port is the bound one when options.port is 0).
    `driver_factory()` builds each connection's driver (default: Driver(config))."""
    config = config or Config()
    options = options or ServerOptions()
    server = _Server(config, options, driver_factory)
    try:
        await asyncio.get_running_loop().run_in_executor(server.pool, probe_driver, server.make_driver)
        async with ws_serve(server.handle, options.host, options.port,
                            max_size=options.max_bytes * WS_SIZE_FACTOR, logger=ws_log,
                            process_request=server.web.process_request if server.web else None) as ws_server:
            port = ws_server.sockets[0].getsockname()[1]
            log.info("drive server listening on ws://%s:%d (lanes %s, signs %s)", options.host, port,
                     config.lanes.method, "on" if config.signs.enabled else "off")
            if server.web:
                log.info("monitor: http://%s:%d/", options.host, port)
            if ready:
                ready(port)
            reporter = asyncio.create_task(server.report_loop())
            try:
                await (stop.wait() if stop else asyncio.Future())
            finally:
                reporter.cancel()
                ws_server.close()  # closes every connection (1001) and waits for their handlers
    finally:
        totals = server.close()
    log.info("drive server stopped: %d frames, %d driven, %d skipped, %d bad; %s", totals["frames"],
             totals["processed"], totals["skipped"], totals["bad"], split_text(totals))
    return totals


def run_server(config: Config, options: ServerOptions) -> dict:
    """Serve in the foreground until Ctrl-C or SIGTERM, then shut down cleanly."""
    async def main() -> dict:
        stop = asyncio.Event()
        loop = asyncio.get_running_loop()
        signals = (signal.SIGINT, signal.SIGTERM)

        def on_signal() -> None:
            log.info("stopping (again to force)")
            for sig in signals:  # a second Ctrl-C interrupts a shutdown that hangs
                loop.remove_signal_handler(sig)
            stop.set()
        for sig in signals:
            loop.add_signal_handler(sig, on_signal)
        return await serve(config, options, stop=stop)
    return asyncio.run(main())


class DriveServer(BackgroundServer):
    """The drive server on a background thread, for tests and `signlane sim --with-driver`:

        with DriveServer(config) as srv:   # listens on a free port
            connect(srv.url) ...
    """

    def __init__(self, config: Config | None = None, options: ServerOptions | None = None,
                 driver_factory: Callable[[], Any] | None = None, start_timeout_s: float = 60.0):
        super().__init__("drive-server", start_timeout_s=start_timeout_s)
        self.config = config or Config()
        self.options = options or ServerOptions(port=0)
        self.driver_factory = driver_factory
        self.totals: dict | None = None

    @property
    def url(self) -> str:
        return f"ws://{self.options.host}:{self.port}"

    async def serve_until(self, stop: asyncio.Event) -> None:
        self.totals = await serve(self.config, self.options, self.driver_factory, self.listening, stop)

