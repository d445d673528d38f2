"""The drive server's bookkeeping: rate-limited error lines and periodic rate/latency reports.

Both live on the server's event loop thread only, so they need no locks.
"""
from __future__ import annotations

import logging
import re
import time
from dataclasses import dataclass, field

import numpy as np

log = logging.getLogger("signlane.drive")


class ErrorLog:
    """One log line per distinct problem; repeats within `window_s` are counted, not printed.

    A misbehaving client can send thousands of identical bad frames a minute; the first line says
    what is wrong, and the next line for that problem (after the window) says how often it recurred.
    Messages that differ only in numbers (byte counts, sizes) count as the same problem."""

    def __init__(self, window_s: float = 10.0, logger: logging.Logger = log):
        self.window_s = window_s
        self.logger = logger
        self._seen: dict[str, tuple[float, int]] = {}  # key -> (time last printed, repeats since)

    def warning(self, text: str, now: float | None = None) -> bool:
        """Log `text` unless it was logged within the window; True if it was printed."""
        now = time.monotonic() if now is None else now
        key = re.sub(r"\d+", "#", text)
        last, repeats = self._seen.get(key, (None, 0))
        if last is not None and now - last < self.window_s:
            self._seen[key] = (last, repeats + 1)
            return False
        more = f" (and {repeats} more like it in the last {now - last:.0f} s)" if repeats else ""
        self.logger.warning("%s%s", text, more)
        self._seen[key] = (now, 0)
        return True


@dataclass
class Rates:
    """Counters and latencies since the last report, plus running totals for the final summary."""

    frames: int = 0  # every text or binary message received
    processed: int = 0  # frames the driver ran on
    skipped: int = 0  # frames answered with the latest command because the driver was busy
    bad: int = 0  # frames answered with the safe command
    step_ms: list[float] = field(default_factory=list)  # decode + Driver.step, in the worker
    answer_ms: list[float] = field(default_factory=list)  # frame received -> answer sent
    totals: dict[str, int] = field(default_factory=lambda: {"frames": 0, "processed": 0, "skipped": 0, "bad": 0})
    since: float = field(default_factory=time.monotonic)

    def report(self, clients: int, now: float | None = None) -> str | None:
        """One line of rates and latencies since the last call (None if nothing arrived), then reset."""
        now = time.monotonic() if now is None else now
        dt = max(now - self.since, 1e-9)
        line = None
        if self.frames:
            line = (f"{clients} client(s): {self.frames / dt:.1f} frames/s in, {self.processed / dt:.1f}/s driven, "
                    f"{self.skipped} skipped (driver busy), {self.bad} bad; step {_ms(self.step_ms)}; "
                    f"answer {_ms(self.answer_ms)}")
        for k in self.totals:
            self.totals[k] += getattr(self, k)
        self.frames = self.processed = self.skipped = self.bad = 0
        self.step_ms, self.answer_ms = [], []
        self.since = now
        return line


def _ms(values: list[float]) -> str:
    if not values:
        return "-"
    a = np.asarray(values)
    return f"median {np.median(a):.1f} ms, p99 {np.percentile(a, 99):.1f} ms"
