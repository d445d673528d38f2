"""Closed-loop driving score over many tracks, per road style: the bundled maps, VIA's own
default maps (../shared/via/maps, when present) and N seeded procedural tracks, in lockstep
(deterministic) and/or real time at 30 Hz through a drive server started in the same process
(as `signlane sim --with-driver`), with the default config (shipped models).

It prints one table per style: a row per (track, mode), a totals row per mode, the acceptance
check (0 off-road events, 100% stop compliance, >= 95% turn compliance, mean cross-track error
<= 0.10 of the lane width: VIA's whole 4 m carriageway, or a painted lane) and, when both modes
ran, the real-time minus lockstep difference per measure.

    python benchmarks/closed_loop.py [--style via painted] [--seeds 20] [--first-seed 0]
                                     [--modes lockstep realtime] [--jobs 1] [--out DIR] [--random-looks]
                                     [--pilot [LABEL=]FILE ...] [--no-teacher] [--looks default random]
                                     [--set KEY=VALUE ...]

With --pilot the same tracks are driven by each pilot as well (`--set pilot.model=FILE`: the
pilot steers, the planner keeps speed, stops and exits), one row per driver: "teacher" (the
classical lane follower), then each pilot under its LABEL (default the file's stem). Train
pilots on other seeds than the ones scored here (`signlane gen pilot` starts at 1000).

Tune on other seeds (e.g. --first-seed 100) than the acceptance's 0-19. Real-time rows depend on
the machine's load: run them with --jobs 1 on a quiet machine. Lockstep rows are deterministic,
so --jobs 2 only changes the wall time.
"""
from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import signal
import sys
import time
from pathlib import Path

from signlane.tables import markdown_row, table

BUNDLED = ["via_town", "loop_demo"]
SHARED_MAPS = Path(__file__).resolve().parents[2] / "shared" / "via" / "maps"
TARGET = {"offroad": 0, "stops": 1.0, "turns": 0.95, "cte_mean": 0.10}


def via_maps(folder: Path = SHARED_MAPS) -> list[str]:
    """VIA's own default maps in `folder` (beside the project: ../shared/via/maps); none, with a
    line on stderr saying so, when it is not there (a checkout elsewhere: pass --via-maps)."""
    if not folder.is_dir():
        print(f"closed_loop: VIA's own maps not found at {folder}: their rows are skipped (--via-maps DIR)",
              file=sys.stderr)
        return []
    return [str(p) for p in sorted(folder.glob("*.json"))]


def _track(name: str, style: str):
    from signlane.world.maps import load_track
    if name.startswith("seed"):
        return load_track("random", style, int(name[4:]))
    return load_track(name, style)


def _label(name: str) -> str:
    return Path(name).stem if name.endswith(".json") else name


def _run(job: tuple) -> dict:
    name, mode, out, random_looks, style, driver, sets = job
    import cv2
    cv2.setNumThreads(1)
    from signlane.config import Config
    from signlane.sim.session import run_session
    from signlane.sim.simulator import SimConfig
    lock = mode == "lockstep"
    t0 = time.perf_counter()
    # a procedural track's scenery (and its camera noise) is seeded by the track's seed, with
    # either looks, as `signlane sim --track random --seed N` seeds it: a row is that command's drive
    looks = SimConfig(random_looks=random_looks, looks_seed=int(name[4:]) if name.startswith("seed") else 0)
    where = f"{style}-{_label(name)}-{mode}-{driver}{'-random' if random_looks else ''}"
    rep = run_session(_track(name, style), looks, Path(out) / where if out else None,
                      Config.load(None, list(sets)), lockstep=lock, with_driver=not lock, show_progress=False)
    rep["wall_s"] = round(time.perf_counter() - t0, 1)
    rep["track"], rep["run"], rep["style"], rep["driver"] = _label(name), mode, style, driver
    rep["looks"] = "random" if random_looks else "default"
    rep["settings"] = list(sets)
    return rep


def _ratio(done: int, need: int) -> str:
    return f"{done}/{need}"


HEADERS = ["track", "driver", "looks", "mode", "laps", "off-road", "cte mean / max", "stops", "turns", "sim s", "fps",
           "latency ms median / p99"]


def _row(r: dict) -> str:
    return markdown_row([r["track"], r.get("driver", "teacher"), r.get("looks", "default"), r["run"], r["laps"], r["offroad_events"], f"{r['cte_mean']:.3f} / {r['cte_max']:.3f}",
                         _ratio(r["stops"]["complied"], r["stops"]["required"]),
                         _ratio(r["turns"]["complied"], r["turns"]["required"]), f"{r['time_s']:.0f}", f"{r['fps']:.1f}",
                         f"{r['latency_ms']['median']:.1f} / {r['latency_ms']['p99']:.1f}"])


def totals(rows: list[dict]) -> dict:
    stops = [sum(r["stops"][k] for r in rows) for k in ("complied", "required")]
    turns = [sum(r["turns"][k] for r in rows) for k in ("complied", "required")]
    time_s = sum(r["time_s"] for r in rows)
    # cross-track mean weighted by driving time, so long tracks count for what they are
    cte = sum(r["cte_mean"] * r["time_s"] for r in rows) / max(time_s, 1e-9)
    out = {"tracks": len(rows), "laps": sum(r["laps"] for r in rows),
           "offroad": sum(r["offroad_events"] for r in rows), "cte_mean": round(cte, 4),
           "cte_max": max(r["cte_max"] for r in rows), "stops": stops, "turns": turns,
           "time_s": round(time_s, 1), "incomplete": [r["track"] for r in rows if r["laps"] < 1],
           "autonomy": round(sum(r["autonomy"] * r["time_s"] for r in rows) / max(time_s, 1e-9), 2)}
    out["pass"] = (out["offroad"] == TARGET["offroad"] and not out["incomplete"]
                   and stops[0] >= TARGET["stops"] * stops[1] and turns[0] >= TARGET["turns"] * turns[1]
                   and cte <= TARGET["cte_mean"])
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--style", nargs="+", choices=["via", "painted"], default=["via", "painted"],
                    help="road styles, one table each (default both)")
    ap.add_argument("--seeds", type=int, default=20, help="procedural tracks seed first..first+N-1 (default 20)")
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--no-bundled", action="store_true", help="skip the bundled and VIA's own maps")
    ap.add_argument("--tracks", nargs="+", help="only these (bundled names, map files or seedN)")
    ap.add_argument("--via-maps", type=Path, default=SHARED_MAPS,
                    help=f"folder of VIA's own maps driven in its style (default {SHARED_MAPS})")
    ap.add_argument("--modes", nargs="+", choices=["lockstep", "realtime"], default=["lockstep"])
    ap.add_argument("--jobs", type=int, default=1, help="tracks driven at once (real time: keep 1)")
    ap.add_argument("--random-looks", action="store_true", help="randomise road and scenery colours (seeded); "
                                                                  "the same as --looks random")
    ap.add_argument("--looks", nargs="+", choices=["default", "random"], help="scenery looks, a row each "
                                                                             "(default: default)")
    ap.add_argument("--pilot", nargs="+", default=[], metavar="[LABEL=]FILE",
                    help="also drive each track with these pilots (rows labelled LABEL, default the file stem)")
    ap.add_argument("--pilot-junctions", choices=["pilot", "planner"], default="planner",
                    help="who steers through planned junctions when a pilot drives: the planner's path "
                         "(default, as the config's pilot.junctions) or the pilot told the exit")
    ap.add_argument("--no-teacher", action="store_true", help="with --pilot: skip the teacher's rows")
    ap.add_argument("--set", dest="sets", action="append", default=[], metavar="KEY=VALUE",
                    help="a config setting for every driver, as `signlane sim --set` (repeatable), e.g. "
                         "lanes.model=runs/road/lanes.onnx to drive on a road model's road")
    ap.add_argument("--out", type=Path, help="per-run report.json and path.png, plus summary.json")
    a = ap.parse_args()
    # `kill` (SIGTERM) unwinds like Ctrl-C, so the pool's `with` terminates its workers instead of
    # leaving them driving (and writing to this run's log) after it
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(128 + signal.SIGTERM))
    looks = a.looks or (["random"] if a.random_looks else ["default"])
    base = tuple(a.sets)
    drivers = [] if a.no_teacher and a.pilot else [("teacher", base)]
    for spec in a.pilot:
        label, _, path = spec.rpartition("=")
        drivers.append((label or Path(path).stem,
                        base + (f"pilot.model={path}", f"pilot.junctions={a.pilot_junctions}")))
    summary = {}
    all_rows = []
    for style in a.style:
        maps = [] if a.no_bundled or a.tracks else BUNDLED + (via_maps(a.via_maps) if style == "via" else [])
        names = a.tracks or maps + [f"seed{s}" for s in range(a.first_seed, a.first_seed + a.seeds)]
        if not names:
            ap.error(f"style {style}: no track to drive (--seeds {a.seeds} and no maps: --no-bundled, or no VIA "
                     f"maps in {a.via_maps}); give --seeds N or --tracks")
        jobs = [(n, m, str(a.out) if a.out else None, lk == "random", style, d, sets)
                for lk in looks for d, sets in drivers for m in a.modes for n in names]
        print(f"\n### style {style}\n")
        print(table(HEADERS, [], markdown=True))
        rows = []
        with mp.get_context("spawn").Pool(a.jobs, maxtasksperchild=1) as pool:
            for r in pool.imap(_run, jobs):
                rows.append(r)
                print(_row(r), flush=True)
        all_rows += rows
        print()
        for lk in looks:
            for d, _ in drivers:
                for m in a.modes:
                    sel = [r for r in rows if r["run"] == m and r["driver"] == d and r["looks"] == lk]
                    t = summary[f"{style}/{lk}/{d}/{m}"] = totals(sel)
                    print(f"{style} {lk} looks, {d}, {m}: {t['tracks']} tracks, {t['laps']} laps, off-road "
                          f"{t['offroad']}, autonomy {t['autonomy']:.1f}%, cte mean {t['cte_mean']:.3f} "
                          f"(max {t['cte_max']:.3f}), stops {_ratio(*t['stops'])}, turns {_ratio(*t['turns'])}, "
                          f"{t['time_s']:.0f} s driven -> {'PASS' if t['pass'] else 'FAIL'}"
                          + (f"; no lap on {t['incomplete']}" if t["incomplete"] else ""))
        rows = [r for r in rows if r["driver"] == drivers[0][0] and r["looks"] == looks[0]]
        if {"lockstep", "realtime"} <= set(a.modes):
            by = {(r["track"], r["run"]): r for r in rows}
            labels = [_label(n) for n in names]
            dc = [abs(by[n, "realtime"]["cte_mean"] - by[n, "lockstep"]["cte_mean"]) for n in labels]
            dt = [abs(by[n, "realtime"]["time_s"] - by[n, "lockstep"]["time_s"]) / by[n, "lockstep"]["time_s"]
                  for n in labels]
            print(f"{style}: real time vs lockstep per track: |d cte mean| max {max(dc):.3f} lane widths, "
                  f"|d lap time| max {100 * max(dt):.1f}%")
    if a.out:
        a.out.mkdir(parents=True, exist_ok=True)
        (a.out / "summary.json").write_text(json.dumps({"rows": all_rows, "totals": summary}, indent=1))


if __name__ == "__main__":
    main()
