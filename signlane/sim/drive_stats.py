"""The drive server's bookkeeping: rate-limited error lines and periodic rate/latency reports.

Both live on the server's event loop thread only, so they need no locks.
"""
from __future__ import annotations

import logging
import re
import time
from collections import deque
from dataclasses import dataclass, field

import numpy as np

log = logging.getLogger("signlane.drive")


class ErrorLog:
    """One log line per distinct problem of each source; repeats within `window_s` are counted,
    not printed.

    A misbehaving client can send thousands of identical bad frames a minute; the first line says
    what is wrong, and the next line for that problem (after the window, or `flush` when the
    client leaves) says how often it recurred. Messages of one source (`who`, e.g. "client 3")
    that differ only in numbers (byte counts, sizes) count as the same problem; another source's
    problem is never folded into them."""

    def __init__(self, window_s: float = 10.0, logger: logging.Logger = log):
        self.window_s = window_s
        self.logger = logger
        # (who, text with numbers masked) -> [time last printed, repeats since, last repeat's line]
        self._seen: dict[tuple[str, str], list] = {}

    def warning(self, text: str, now: float | None = None, who: str = "") -> bool:
        """Log `who: text` unless it was logged within the window; True if it was printed."""
        now = time.monotonic() if now is None else now
        key = (who, re.sub(r"\d+", "#", text))
        line = f"{who}: {text}" if who else text
        seen = self._seen.get(key)
        if seen is not None and now - seen[0] < self.window_s:
            seen[1] += 1
            seen[2] = line
            return False
        more = f" (and {seen[1]} more like it in the last {now - seen[0]:.0f} s)" if seen and seen[1] else ""
        self.logger.warning("%s%s", line, more)
        self._seen[key] = [now, 0, line]
        return True

    def flush(self, who: str | None = None, now: float | None = None) -> int:
        """A summary line for each problem repeated since it was printed: every problem of `who`
        (a source that is gone), or with `who` None those whose window has passed (call it now and
        then: it also forgets problems with nothing left to report). Returns the lines printed."""
        now = time.monotonic() if now is None else now
        printed = 0
        for key, (t, repeats, line) in list(self._seen.items()):
            if (who is not None and key[0] != who) or (who is None and now - t < self.window_s):
                continue
            if repeats:
                self.logger.warning("%s (repeated %d times in the last %.0f s)", line, repeats, now - t)
                printed += 1
            if who is not None or not repeats:
                del self._seen[key]  # nothing left to report: the next occurrence prints again
            else:
                self._seen[key] = [now, 0, line]
        return printed


RUN_SAMPLES = 20000


SPLIT = ("decode", "perceive", "answer")


def split_ms() -> dict[str, deque]:
    """Empty latency lists of one run or connection: the last RUN_SAMPLES of each stage's ms."""
    return {k: deque(maxlen=RUN_SAMPLES) for k in SPLIT}


def split_summary(ms: dict) -> dict[str, float]:
    """{stage}_ms_median and {stage}_ms_p99 of lists of ms per stage (stages without any left out)."""
    out = {}
    for k, v in ms.items():
        if v:
            out[f"{k}_ms_median"] = round(float(np.median(v)), 2)
            out[f"{k}_ms_p99"] = round(float(np.percentile(v, 99)), 2)
    return out


def split_text(summary: dict) -> str:
    """decode / perceive / answer medians and p99s of a split_summary, for a log line."""
    parts = [f"{k} median {summary[f'{k}_ms_median']:.1f} ms, p99 {summary[f'{k}_ms_p99']:.1f} ms"
             for k in SPLIT if f"{k}_ms_median" in summary]
    return "; ".join(parts) or "no frames driven"


@dataclass
class Rates:
    """Counters and latencies since the last report, plus running totals for the final summary."""

    frames: int = 0  # every text or binary message received
    processed: int = 0  # frames the driver ran on
    skipped: int = 0  # frames answered with the latest command because the driver was busy
    bad: int = 0  # frames answered with the safe command
    decode_ms: list[float] = field(default_factory=list)  # the message decoded, in the worker
    perceive_ms: list[float] = field(default_factory=list)  # Driver.step (perception, planning, control)
    answer_ms: list[float] = field(default_factory=list)  # frame received -> answer sent (waits included)
    totals: dict[str, int] = field(default_factory=lambda: {"frames": 0, "processed": 0, "skipped": 0, "bad": 0})
    # the run's latencies for its summary (the last RUN_SAMPLES of each: a long run stays bounded)
    run_ms: dict[str, deque] = field(default_factory=split_ms)
    since: float = field(default_factory=time.monotonic)

    def report(self, clients: int, now: float | None = None) -> str | None:
        """One line of rates and latencies since the last call (None if nothing arrived), then reset."""
        now = time.monotonic() if now is None else now
        dt = max(now - self.since, 1e-9)
        line = None
        if self.frames:
            line = (f"{clients} client(s): {self.frames / dt:.1f} frames/s in, {self.processed / dt:.1f}/s driven, "
                    f"{self.skipped} skipped (driver busy), {self.bad} bad; decode {_ms(self.decode_ms)}; "
                    f"perceive {_ms(self.perceive_ms)}; answer {_ms(self.answer_ms)}")
        for k in self.totals:
            self.totals[k] += getattr(self, k)
        for k in self.run_ms:
            self.run_ms[k].extend(getattr(self, f"{k}_ms"))
        self.frames = self.processed = self.skipped = self.bad = 0
        self.decode_ms, self.perceive_ms, self.answer_ms = [], [], []
        self.since = now
        return line

    def summary(self) -> dict[str, float]:
        """Median and p99 ms of decode, perceive and answer over the run (call after report)."""
        return split_summary(self.run_ms)


def _ms(values: list[float]) -> str:
    if not values:
        return "-"
    a = np.asarray(values)
    return f"median {np.median(a):.1f} ms, p99 {np.percentile(a, 99):.1f} ms"
