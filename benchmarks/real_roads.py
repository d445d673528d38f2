"""Lane methods on real road footage from a camera nobody measured (../shared/real_roads: a
highway video and six photos), as `signlane infer` runs them with no camera setting: the camera
each input is read with (estimated from its frames), the share of frames with an ego lane, and
the share of frame pairs whose offset moves less than 0.1 lane widths (a lost frame counts as a
jump). With --out DIR each method's annotated video, contact sheet and photos go to DIR/METHOD.

    python benchmarks/real_roads.py [--method auto segnet ...] [--out DIR] [--set KEY=VALUE ...]
"""
from __future__ import annotations

import argparse
import contextlib
import io
import json
import sys
from pathlib import Path

import numpy as np

from signlane.cli import main as cli
from signlane.tables import table

REAL = Path(__file__).resolve().parents[2] / "shared" / "real_roads"


def run(method: str, out: Path | None, sets: list[str]) -> dict:
    args = ["infer", "--no-progress", str(REAL / "solidWhiteRight.mp4"), str(REAL / "images"), "--lanes", method,
            "--json", "-", "--set", "signs.enabled=false"]
    for kv in sets:
        args += ["--set", kv]
    if out is not None:
        args += ["--out", str(out / method)]
    buf, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(buf), contextlib.redirect_stderr(err):
        code = cli(args)
    if code != 0:
        raise SystemExit(f"{method}: infer failed: {err.getvalue().strip().splitlines()[-1:]}")
    recs = [json.loads(line) for line in buf.getvalue().splitlines()]
    video = [r for r in recs if r["source"].endswith(".mp4")]
    photos = [r for r in recs if not r["source"].endswith(".mp4")]
    found = np.array([r["lane"]["found"] for r in video])
    offset = np.array([r["lane"]["offset"] for r in video])
    steady = (np.abs(np.diff(offset)) < 0.1) & found[1:] & found[:-1]
    cam = video[0].get("camera", {})
    return {"method": method, "frames": len(video), "found %": f"{100 * found.mean():.1f}",
            "steady %": f"{100 * steady.mean():.1f}", "max jump": f"{np.abs(np.diff(offset)).max():.3f}",
            "photos found": f"{sum(r['lane']['found'] for r in photos)}/{len(photos)}",
            "camera": f"pitch {cam.get('pitch_deg', float('nan')):+.1f} h {cam.get('height_m', float('nan')):.2f}"
                      + (" (estimated)" if cam.get("estimated") else "")}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--method", nargs="+", default=["auto", "sliding-window", "segnet"])
    ap.add_argument("--out", type=Path, help="write each method's annotated outputs under DIR/METHOD")
    ap.add_argument("--set", dest="sets", action="append", default=[], help="a config override for infer")
    args = ap.parse_args(argv)
    if not REAL.is_dir():
        print(f"{REAL} is absent: nothing to measure", file=sys.stderr)
        return 1
    rows = [run(m, args.out, args.sets) for m in args.method]
    keys = list(rows[0])
    print(table(keys, [[r[k] for k in keys] for r in rows]))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
