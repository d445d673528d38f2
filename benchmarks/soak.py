"""Drive-server soak: VIA's frame stream at a steady rate for minutes; every frame must be
answered and the server's memory must stay flat.

The server is `signlane drive` in a child process (default config: lanes, junctions, signs in
their own thread). The client sends pre-rendered 640x480 VIA messages of a consecutive drive at
`--fps` on a fixed clock without waiting for answers (as VIA does), and reads answers on a second
thread. The server's resident memory (VmRSS) is sampled every second; growth is the last sample
minus the sample after `--warmup` seconds (models, buffers and the first frames' caches are
allocated by then).

    python benchmarks/soak.py                        # 60 frames/s for 180 s, 640x480
    python benchmarks/soak.py --seconds 20 --check   # exit code 1 unless every frame was
                                                     # answered and growth <= --max-growth-mb
"""
from __future__ import annotations

import argparse
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

from websockets.sync.client import connect

from signlane.sim.protocol import encode_jpeg, encode_telemetry
from signlane.world.sampling import DriveSampler, SamplerConfig
from signlane.tables import pairs


def rss_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024.0
    raise RuntimeError(f"no VmRSS for process {pid}")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def frames(n: int, width: int, height: int, fps: float) -> list[str]:
    """n consecutive VIA messages along a drive (lane tracking sees a moving road)."""
    drive = DriveSampler(3, SamplerConfig(width, height, effects="normal"), speed_mps=8.0, fps=fps)
    return [encode_telemetry(0.0, 0.4, 8.0, encode_jpeg(drive.sample(i).image)) for i in range(n)]


def start_server(port: int) -> subprocess.Popen:
    proc = subprocess.Popen([sys.executable, "-m", "signlane.cli", "drive", "--port", str(port), "--log-every", "30"],
                            stderr=subprocess.PIPE, text=True)
    t0 = time.monotonic()
    while time.monotonic() - t0 < 120:
        try:
            with socket.create_connection(("127.0.0.1", port), timeout=1):
                return proc
        except OSError:
            if proc.poll() is not None:
                raise RuntimeError(f"the drive server exited: {proc.stderr.read()}")
            time.sleep(0.2)
    proc.kill()
    raise RuntimeError("the drive server did not start within 120 s")


def soak(seconds: float, fps: float, width: int, height: int, warmup: float) -> dict:
    messages = frames(60, width, height, fps)
    port = free_port()
    server = start_server(port)
    samples: list[tuple[float, float]] = []
    answered = [0]
    try:
        with connect(f"ws://127.0.0.1:{port}", max_size=None) as ws:
            def reader():
                try:
                    while True:
                        ws.recv(timeout=30)
                        answered[0] += 1
                except Exception:  # closed at the end (or a 30 s silence: counted as unanswered)
                    pass
            rd = threading.Thread(target=reader, daemon=True)
            rd.start()
            t0 = time.monotonic()
            sent, next_sample = 0, 0.0
            while (now := time.monotonic() - t0) < seconds:
                if now >= next_sample:
                    samples.append((now, rss_mb(server.pid)))
                    next_sample += 1.0
                due = int(now * fps) + 1
                while sent < due:
                    ws.send(messages[sent % len(messages)])
                    sent += 1
                time.sleep(max(0.0, (sent / fps) - (time.monotonic() - t0)))
            samples.append((time.monotonic() - t0, rss_mb(server.pid)))
            deadline = time.monotonic() + 30
            while answered[0] < sent and time.monotonic() < deadline:
                time.sleep(0.05)
    finally:
        server.send_signal(signal.SIGINT)
        try:
            _, err = server.communicate(timeout=60)
        except subprocess.TimeoutExpired:
            server.kill()
            _, err = server.communicate()
    warm = next(m for t, m in samples if t >= warmup) if any(t >= warmup for t, _ in samples) else samples[0][1]
    stopped = [line for line in err.splitlines() if "drive server stopped" in line]
    return {"seconds": round(samples[-1][0], 1), "fps_target": fps, "sent": sent, "answered": answered[0],
            "rss_start_mb": round(samples[0][1], 1), "rss_after_warmup_mb": round(warm, 1),
            "rss_end_mb": round(samples[-1][1], 1), "rss_max_mb": round(max(m for _, m in samples), 1),
            "growth_mb": round(samples[-1][1] - warm, 1), "server": stopped[-1].split(": ", 1)[-1] if stopped else "",
            "warnings": [line for line in err.splitlines() if line.startswith(("WARNING", "ERROR"))][:5]}


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--seconds", type=float, default=180.0)
    p.add_argument("--fps", type=float, default=60.0)
    p.add_argument("--size", default="640x480")
    p.add_argument("--warmup", type=float, default=10.0, help="seconds before the memory baseline (default 10)")
    p.add_argument("--max-growth-mb", type=float, default=20.0)
    p.add_argument("--check", action="store_true", help="exit 1 unless every frame was answered and memory stayed flat")
    args = p.parse_args()
    w, h = (int(v) for v in args.size.split("x"))
    r = soak(args.seconds, args.fps, w, h, min(args.warmup, args.seconds / 3))
    print(pairs(r.items()))
    ok = r["answered"] == r["sent"] and r["growth_mb"] <= args.max_growth_mb
    print("OK" if ok else "FAILED: " + ("unanswered frames" if r["answered"] != r["sent"] else
                                        f"memory grew {r['growth_mb']} MB > {args.max_growth_mb} MB"))
    return 0 if ok or not args.check else 1


if __name__ == "__main__":
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    sys.exit(main())
