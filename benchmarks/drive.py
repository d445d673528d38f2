"""Drive-server speed: latency per frame (median, p99) at 640x480 for each lane method, through a
real WebSocket round trip, and the frame rates the server sustains.

The server runs in a child process (as `signlane drive` would, so client and server do not share
a GIL); the client sends pre-rendered VIA messages (640x480 JPEG, base64, string fields) of a
consecutive drive, so lane tracking behaves as on the road.
  lockstep: send a frame, wait for its answer, repeat (what `signlane sim --lockstep` does);
            latency is that round trip, fps = frames / time.
  flood:    send every frame back to back without waiting (what VIA does when the server is
            slower than the simulator); answers/s and the share of frames actually driven (the
            rest were answered at once with the latest command).
The baseline is a server whose driver does nothing: JSON + base64 + JPEG decode and the WebSocket
round trip only. It runs beside every row and is timed right before it in each repeat; 'x base'
is the median over repeats of (row median / baseline median), robust to load drifting mid-run.

    python benchmarks/drive.py [--frames 40] [--repeats 3] [--method NAME ...]

Lane-method rows run with signs off; the last row is the default config (signs on).
"""
from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import statistics
import time
from dataclasses import replace

import numpy as np
from websockets.sync.client import connect

from signlane import lanes
from signlane.config import Config
from signlane.sim.protocol import encode_jpeg, encode_telemetry
from signlane.types import Command, LaneEstimate, Perception
from signlane.world.sampling import DriveSampler, SamplerConfig
from signlane.tables import table

BASELINE = "baseline (decode only)"


class NullDriver:
    """Decoding happens in the server before the driver: this driver only answers."""

    def step(self, telemetry):
        return Perception(None, LaneEstimate("none", False)), Command(0.0, 0.2, "cruise")

    def close(self):
        pass


def _child(method: str | None, signs: bool, conn) -> None:
    """Server process: serve until the parent says stop, then send back the server's totals."""
    import logging
    logging.basicConfig(level=logging.WARNING)
    from signlane.config import Config
    from signlane.sim.server import DriveServer, ServerOptions
    cfg = Config()
    cfg = replace(cfg, signs=replace(cfg.signs, enabled=signs))
    if method:
        cfg = replace(cfg, lanes=replace(cfg.lanes, method=method))
    try:
        srv = DriveServer(cfg, ServerOptions(port=0, log_every_s=3600),
                          driver_factory=None if method else NullDriver).start()
    except Exception as e:
        conn.send(("error", f"{type(e).__name__}: {e}"))
        return
    conn.send(("port", srv.port))
    conn.recv()
    srv.close()
    conn.send(("totals", srv.totals))


def lockstep(url: str, messages: list[bytes]) -> tuple[list[float], float]:
    """Round-trip ms per frame and frames/s, one frame in flight."""
    rtt = []
    with connect(url, max_size=None) as ws:
        t_start = time.perf_counter()
        for m in messages:
            t0 = time.perf_counter()
            ws.send(m)
            json.loads(ws.recv())
            rtt.append((time.perf_counter() - t0) * 1e3)
        fps = len(messages) / (time.perf_counter() - t_start)
    return rtt, fps


def flood(url: str, messages: list[bytes]) -> float:
    """Answers/s when every frame is sent without waiting for answers."""
    with connect(url, max_size=None) as ws:
        t0 = time.perf_counter()
        for m in messages:
            ws.send(m)
        for _ in messages:
            ws.recv()
        return len(messages) / (time.perf_counter() - t0)


class ChildServer:
    """A drive server in a child process: `with ChildServer(method, signs) as url:`."""

    def __init__(self, method: str | None, signs: bool):
        ctx = mp.get_context("spawn")
        self.conn, child = ctx.Pipe()
        self.proc = ctx.Process(target=_child, args=(method, signs, child), daemon=True)
        self.totals: dict = {}

    def __enter__(self) -> str:
        self.proc.start()
        kind, value = self.conn.recv()
        if kind == "error":
            self.proc.join(30)
            raise RuntimeError(value)
        return f"ws://127.0.0.1:{value}"

    def __exit__(self, *exc) -> None:
        if self.proc.is_alive():
            self.conn.send("stop")
            self.totals = self.conn.recv()[1]
        self.proc.join(30)


def measure(name: str, method: str | None, signs: bool, messages: list[bytes], repeats: int,
            base_url: str) -> dict:
    """One row. Each repeat times the baseline server right before this one, so the ratio
    compares the two under the same load (the machine is shared; absolute numbers drift)."""
    srv = ChildServer(method, signs)
    try:
        with srv as url:
            lockstep(url, messages[:5])  # warm up: first-frame setup, model load, caches
            runs, base_runs = [], []
            for _ in range(repeats):
                base_runs.append(lockstep(base_url, messages))
                runs.append(lockstep(url, messages))
            answers_s = statistics.median(flood(url, messages) for _ in range(repeats))
    except RuntimeError as e:
        return {"name": name, "error": str(e)}
    flood_frames = repeats * len(messages)
    if srv.totals["bad"]:
        return {"name": name, "error": f"the driver failed on {srv.totals['bad']} frames (see the log above)"}
    return {"name": name, "median": statistics.median(float(np.median(r)) for r, _ in runs),
            "p99": statistics.median(float(np.percentile(r, 99)) for r, _ in runs),
            "ratio": statistics.median(float(np.median(r) / np.median(b)) for (r, _), (b, _) in zip(runs, base_runs)),
            "base": statistics.median(float(np.median(b)) for b, _ in base_runs),
            "fps": statistics.median(f for _, f in runs), "flood": answers_s,
            # lockstep never skips, so every skip happened during the floods
            "driven": 100.0 * (1 - srv.totals["skipped"] / flood_frames),
            # inside the server over the whole run (lockstep and floods): its own split of the time
            "decode": srv.totals.get("decode_ms_median", float("nan")),
            "perceive": srv.totals.get("perceive_ms_median", float("nan"))}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=40, help="frames per repeat (default 40)")
    ap.add_argument("--repeats", type=int, default=3, help="repeats; the table shows medians (default 3)")
    ap.add_argument("--method", action="append", help="lane method(s) (default: all available)")
    ap.add_argument("--seed", type=int, default=4)
    args = ap.parse_args()
    sampler = DriveSampler(args.seed, SamplerConfig(640, 480, effects="normal"))
    messages = [encode_telemetry(0.0, 0.5, 8.0, encode_jpeg(sampler.sample(i).image), time=i / 30)
                for i in range(args.frames)]
    kb = np.mean([len(m) for m in messages]) / 1024
    with ChildServer(None, False) as base_url:
        lockstep(base_url, messages[:5])
        rows = [measure(BASELINE, None, False, messages, args.repeats, base_url)]
        for m in args.method or lanes.available():
            rows.append(measure(m, m, False, messages, args.repeats, base_url))
        default = Config().lanes.method  # and the default driver as `signlane drive` runs it: signs on
        rows.append(measure(f"{default} + signs", default, True, messages, args.repeats, base_url))
    print(f"640x480 frames, {kb:.0f} KB per message, {args.frames} frames x {args.repeats} repeats (medians)")
    print(table(["server", "answer median ms", "answer p99 ms", "decode ms", "perceive ms", "base ms", "x base",
                 "lockstep fps", "flood ans/s", "driven %"],
                [[r["name"], f"{r['median']:.1f}", f"{r['p99']:.1f}", f"{r['decode']:.1f}", f"{r['perceive']:.1f}",
                  f"{r['base']:.1f}", f"{r['ratio']:.2f}", f"{r['fps']:.1f}", f"{r['flood']:.0f}", f"{r['driven']:.0f}"]
                 for r in rows if "error" not in r]))
    for r in rows:
        if "error" in r:
            print(f"{r['name']}: unavailable: {r['error'][:90]}")
    print("answer: message in -> answer out at the client (lockstep); decode and perceive: the server's own split "
          "(medians over the run); base ms: the baseline server timed in the same repeats; x base: median of "
          "per-repeat ratios. "
          "Shared 2-core machine: absolute times are upper bounds.")

if __name__ == "__main__":
    main()
