"""Drive-server speed: latency per frame (median, p99) at 640x480 for each lane method, through a
real WebSocket round trip, and the frame rates the server sustains.

The server runs in a child process (as `signlane drive` would, so client and server do not share
a GIL); the client sends pre-rendered VIA messages (640x480 JPEG, base64, string fields) of a
consecutive drive, so lane tracking behaves as on the road.
  lockstep: send a frame, wait for its answer, repeat (what `signlane sim --lockstep` does);
            latency is that round trip, fps = frames / time.
  30 fps:   the same round trip with frames sent at 30 frames/s, as VIA sends them (the sign
            worker of the real-time server then runs between frames, not against the next one).
  flood:    send every frame back to back without waiting (what VIA does when the server is
            slower than the simulator); answers/s and the share of frames actually driven (the
            rest were answered at once with the latest command).
The baseline is a server whose driver does nothing: JSON + base64 + JPEG decode and the WebSocket
round trip only. It runs beside every row and is timed right before it in each repeat; 'x base'
is the median over repeats of (row median / baseline median), robust to load drifting mid-run.

    python benchmarks/drive.py [--frames 40] [--repeats 3] [--method NAME ...] [--viewers N]
                               [--style painted|via|mixed] [--looks random|default]

Lane-method rows run with signs off; the last row is the default config (signs on). The server
reports its own split of each frame's time for each connection (its log line when the connection
ends): decode (JSON, base64, JPEG), perceive (the driver) and answer (message in -> answer sent,
decode and waits included); the table shows it for the 30 frames/s runs (median over repeats of
each run's median and p99): the server's answer latency without the client's own socket work.

--viewers N: each row also runs lockstep with N monitor viewers attached (a child process that
streams /monitor as the page does: each JPEG decoded, then acked) right after a run with none,
in every repeat, and a second table compares the answer latency (median, p99) of the two.
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
from signlane.camera import via_camera
from signlane.config import Config
from signlane.sim.protocol import encode_jpeg, encode_telemetry
from signlane.types import Command, LaneEstimate, Perception
from signlane.world.sampling import DriveSampler, SamplerConfig
from signlane.tables import table

BASELINE = "baseline (decode only)"
PACED_FPS = 30.0  # the paced run's frame rate: VIA's
PACED_PATH = "/paced"  # the paced runs' connections ask for this path, which the server records


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


def _viewers_child(url: str, n: int, conn) -> None:
    """N monitor viewers that stream until told to stop, decoding every JPEG as a page would;
    sends back the frames each received."""
    import threading
    import cv2
    from websockets.sync.client import connect as ws_connect
    stop, joined = threading.Event(), threading.Barrier(n + 1)
    counts = [0] * n

    def view(i: int) -> None:
        with ws_connect(f"{url}/monitor", max_size=None) as ws:
            joined.wait()
            while not stop.is_set():
                try:
                    msg = ws.recv(timeout=0.2)
                except TimeoutError:
                    continue
                if isinstance(msg, bytes):
                    cv2.imdecode(np.frombuffer(msg, np.uint8), cv2.IMREAD_COLOR)
                    counts[i] += 1
                    ws.send(json.dumps({"ack": counts[i]}))
    threads = [threading.Thread(target=view, args=(i,), daemon=True) for i in range(n)]
    for t in threads:
        t.start()
    joined.wait()
    conn.send("ready")
    conn.recv()
    stop.set()
    for t in threads:
        t.join(5)
    conn.send(counts)


class Viewers:
    """`with Viewers(url, n):` N monitor viewers attached (in a child process: they must not share
    the timing client's GIL); .counts afterwards."""

    def __init__(self, url: str, n: int):
        ctx = mp.get_context("spawn")
        self.conn, child = ctx.Pipe()
        self.proc = ctx.Process(target=_viewers_child, args=(url, n, child), daemon=True)
        self.counts: list[int] = []

    def __enter__(self) -> "Viewers":
        self.proc.start()
        assert self.conn.recv() == "ready"
        return self

    def __exit__(self, *exc) -> None:
        self.conn.send("stop")
        self.counts = self.conn.recv()
        self.proc.join(30)


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


def paced(url: str, messages: list[bytes], fps: float) -> list[float]:
    """Round-trip ms per frame with frames sent at `fps` (VIA renders at 30 frames/s): a frame,
    its answer, then a wait for the next tick, so that work the server does between frames (the
    sign worker on the newest frame) runs in the gaps as it does against the simulator."""
    rtt = []
    period = 1.0 / fps
    with connect(url, max_size=None) as ws:
        t_next = time.perf_counter()
        for m in messages:
            time.sleep(max(0.0, t_next - time.perf_counter()))
            t0 = time.perf_counter()
            ws.send(m)
            json.loads(ws.recv())
            rtt.append((time.perf_counter() - t0) * 1e3)
            t_next = max(t_next + period, time.perf_counter())  # a late answer does not queue a burst
    return rtt


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
            base_url: str, viewers: int = 0, viewer_frames: int = 300) -> dict:
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
            # the server tells its 30-frames/s connections apart from the rest by their path
            at_fps = [paced(url + PACED_PATH, messages, PACED_FPS) for _ in range(repeats)]
            watched = []  # (no viewers, N viewers) lockstep runs back to back, their order alternating
            long = (messages * (1 + viewer_frames // len(messages)))[:viewer_frames]
            for k in range(repeats if viewers and method else 0):
                if k % 2:
                    with Viewers(url, viewers) as v:
                        seen = lockstep(url, long)[0]
                    alone = lockstep(url, long)[0]
                else:
                    alone = lockstep(url, long)[0]
                    with Viewers(url, viewers) as v:
                        seen = lockstep(url, long)[0]
                watched.append((alone, seen, sum(v.counts)))
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
            "paced_median": statistics.median(float(np.median(r)) for r in at_fps),
            "paced_p99": statistics.median(float(np.percentile(r, 99)) for r in at_fps),
            # lockstep never skips, so every skip happened during the floods
            "driven": 100.0 * (1 - srv.totals["skipped"] / flood_frames),
            # inside the server, its 30 frames/s connections only: its own split of the time
            # (median over repeats of each connection's median and p99)
            **paced_split(srv.totals.get("connections", [])),
            "watched": watched}


def paced_split(connections: list[dict]) -> dict[str, float]:
    """decode / perceive / answer median and p99 of the server's 30 frames/s connections (the
    median over them of each one's own figure)."""
    paced = [c for c in connections if c.get("path") == PACED_PATH]
    return {f"{k}_{q}": statistics.median(c.get(f"{k}_ms_{q}", float("nan")) for c in paced) if paced else float("nan")
            for k in ("decode", "perceive", "answer") for q in ("median", "p99")}


def viewer_table(rows: list[dict], viewers: int) -> str:
    """Answer latency at the client with no viewers and with N: median and p99 over all the
    repeats' frames of each, their difference, and the median of the per-repeat p99 differences."""
    out = []
    for r in rows:
        w = r.get("watched")
        if not w:
            continue
        alone = np.concatenate([a for a, _, _ in w])
        seen = np.concatenate([b for _, b, _ in w])
        p99 = lambda a: float(np.percentile(a, 99))  # noqa: E731
        out.append([r["name"], f"{np.median(alone):.1f}", f"{np.median(seen):.1f}",
                    f"{np.median(seen) - np.median(alone):+.1f}", f"{p99(alone):.1f}", f"{p99(seen):.1f}",
                    f"{p99(seen) - p99(alone):+.1f}", f"{statistics.median(p99(b) - p99(a) for a, b, _ in w):+.1f}",
                    f"{p99(seen) / p99(alone):.2f}", f"{sum(n for _, _, n in w) / len(seen):.2f}"])
    return table(["server", "median 0 viewers", f"median {viewers} viewers", "diff", "p99 0 viewers",
                  f"p99 {viewers} viewers", "diff", "per-repeat diff", "p99 ratio", "viewer frames/driven"], out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=40, help="frames per repeat (default 40)")
    ap.add_argument("--repeats", type=int, default=3, help="repeats; the table shows medians (default 3)")
    ap.add_argument("--method", action="append", help="lane method(s) (default: all available)")
    ap.add_argument("--seed", type=int, default=4)
    ap.add_argument("--style", choices=["painted", "via", "mixed"], default="painted",
                    help="the drive's road (default painted; with random looks it may have no centre line)")
    ap.add_argument("--looks", choices=["random", "default"], default="random",
                    help="randomised looks (default) or the style's own (a painted road then has its dashed "
                         "centre line); the camera is VIA's either way, the one the drive server is configured for")
    ap.add_argument("--viewers", type=int, default=0,
                    help="also compare lockstep answer latency with this many monitor viewers attached (default 0)")
    ap.add_argument("--viewer-frames", type=int, default=300,
                    help="frames per run of the viewer comparison (the messages cycled; default 300)")
    args = ap.parse_args()
    sampler = DriveSampler(args.seed, SamplerConfig(640, 480, effects="normal", style=args.style,
                                                    randomise=args.looks == "random"),
                           camera=via_camera(640, 480))  # VIA's, as the server's default config assumes
    messages = [encode_telemetry(0.0, 0.5, 8.0, encode_jpeg(sampler.sample(i).image), time=i / 30)
                for i in range(args.frames)]
    kb = np.mean([len(m) for m in messages]) / 1024
    with ChildServer(None, False) as base_url:
        lockstep(base_url, messages[:5])
        rows = [measure(BASELINE, None, False, messages, args.repeats, base_url)]
        for m in args.method or lanes.available():
            rows.append(measure(m, m, False, messages, args.repeats, base_url, args.viewers, args.viewer_frames))
        default = Config().lanes.method  # and the default driver as `signlane drive` runs it: signs on
        rows.append(measure(f"{default} + signs", default, True, messages, args.repeats, base_url, args.viewers,
                            args.viewer_frames))
    print(f"640x480 frames ({args.style} road, {args.looks} looks, seed {args.seed}), {kb:.0f} KB per message, "
          f"{args.frames} frames x {args.repeats} repeats (medians)")
    print(table(["server", "answer median ms", "answer p99 ms", "30 fps med/p99", "30 fps decode", "30 fps perceive",
                 "30 fps server answer", "base ms", "x base", "lockstep fps", "flood ans/s", "driven %"],
                [[r["name"], f"{r['median']:.1f}", f"{r['p99']:.1f}", f"{r['paced_median']:.1f} / {r['paced_p99']:.1f}",
                  f"{r['decode_median']:.1f} / {r['decode_p99']:.1f}",
                  f"{r['perceive_median']:.1f} / {r['perceive_p99']:.1f}",
                  f"{r['answer_median']:.1f} / {r['answer_p99']:.1f}", f"{r['base']:.1f}", f"{r['ratio']:.2f}",
                  f"{r['fps']:.1f}", f"{r['flood']:.0f}", f"{r['driven']:.0f}"]
                 for r in rows if "error" not in r]))
    if args.viewers:
        print(f"\nanswer latency at the client (ms), lockstep, without and with {args.viewers} monitor viewers: the "
              f"same server, {args.repeats} pair(s) of {args.viewer_frames}-frame runs back to back, their order "
              "alternating; statistics over all frames of each condition")
        print(viewer_table([r for r in rows if "error" not in r], args.viewers))
    for r in rows:
        if "error" in r:
            print(f"{r['name']}: unavailable: {r['error'][:90]}")
    print("answer: message in -> answer out at the client (lockstep: the next frame sent at once); 30 fps: the "
          "same, frames sent at 30 frames/s as VIA does; 30 fps decode, perceive and server answer: the "
          "server's own split of those runs (median / p99; server answer: message in -> answer out, decode "
          "included); base ms: the baseline server timed in the same repeats; x base: median of per-repeat ratios. "
          "Shared 2-core machine: absolute times are upper bounds.")

if __name__ == "__main__":
    main()
