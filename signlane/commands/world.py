"""`signlane gen`, `demo` and `map`: synthetic data and tracks."""
from __future__ import annotations

import argparse
import json
from pathlib import Path

from signlane.commands.common import UserError, positive, size_arg


# --- gen ---------------------------------------------------------------------------------------
def add_gen(sub) -> None:
    p = sub.add_parser("gen", help="generate synthetic datasets (lanes, signs, drive, pilot)",
                       description="Generate seeded synthetic datasets from the world renderer. The same "
                                   "seed gives the same files whatever --workers; an interrupted run is "
                                   "completed with --resume.")
    kinds = p.add_subparsers(dest="kind", required=True, metavar="{lanes,signs,drive,pilot}")
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--n", type=positive, required=True,
                        help="how many: lanes and drive = frames; signs = crops (about n, in ImageFolder class "
                             "folders, with classes.txt and the train.txt / val.txt split; n/4 rendered frames "
                             "supply the real ones)")
    common.add_argument("--out", type=Path, required=True, help="output folder")
    common.add_argument("--seed", type=int, default=0, help="dataset seed (default 0)")
    common.add_argument("--resume", action="store_true", help="complete an interrupted run in --out")
    common.add_argument("--preview", action="store_true", help="also write contact sheets (preview*.png)")
    common.add_argument("--style", choices=["painted", "via", "mixed"],
                        help="road style of the tracks: painted lanes, VIA's kerbed carriageway (no paint: its "
                             "marking masks are empty), or mixed (half each, per track); default painted for "
                             "lanes and signs, via for drive")
    lanes = kinds.add_parser("lanes", parents=[common], help="frames + lane-marking masks + labels.jsonl",
                             description="Frames with exact lane-marking masks and labels (images/, masks/, "
                                         "labels.jsonl, manifest.json). Masks are class ids: 0 background, "
                                         "1 lane marking, 255 no label (kerbs, and paint the frame does not show: "
                                         "night, fog, glare or a pale look can leave it the road's colour).")
    lanes.add_argument("--size", type=size_arg, default=(320, 240), help="frame size WxH (default 320x240)")
    lanes.add_argument("--workers", type=positive, default=1, help="worker processes (default 1)")
    lanes.add_argument("--effects", choices=["clean", "normal", "hard", "heavy", "mixed", "wild"], default="mixed",
                       help="photometric/pose randomisation (default mixed: normal and hard; wild: normal, "
                            "hard and heavy = night, rain, stronger light and pose changes)")
    lanes.add_argument("--preset", choices=["default", "heavy", "world"], default="default",
                       help="heavy: wild effects, strong wear and shadows, wider camera spread, a third of the "
                            "frames 16:9 (for lane-segmentation training; overrides --effects); world: heavy, "
                            "and half the frames from any camera (0.2-3 m high, pitched 0-25 degrees, "
                            "50-120 degrees field of view: for road models that meet unmeasured cameras)")
    lanes.add_argument("--drivable", action="store_true",
                       help="also write drivable/<id>.png (class ids: 1 road surface, 0 not)")
    lanes.add_argument("--junctions", type=float, default=0.0, metavar="SHARE",
                       help="share of the frames (0..1) placed 1-30 m before a junction of the route, so that "
                            "side roads are in view (road models see too few of them in frames placed anywhere; "
                            "default 0)")
    lanes.add_argument("--no-randomise", dest="randomise", action="store_false",
                       help="default road style, looks and camera instead of randomised ones")
    signs = kinds.add_parser("signs", parents=[common], help="labelled sign crops (ImageFolder)",
                             description="Sign crops in ImageFolder layout <class>/<id>.png with VIA class "
                                         "names, including 'unknown' crops of red/blue non-signs.")
    signs.add_argument("--crop", type=positive, default=48, help="crop size in pixels (default 48)")
    signs.add_argument("--workers", type=positive, default=1, help="worker processes (default 1)")
    drive = kinds.add_parser("drive", parents=[common], help="a frame sequence along one track (+ drive.mp4)",
                             description="Consecutive frames along one seeded track, in the lanes layout, "
                                         "plus drive.mp4.")
    drive.add_argument("--size", type=size_arg, default=(640, 480), help="frame size WxH (default 640x480)")
    drive.add_argument("--fps", type=float, default=30.0, help="frames per second of the drive (default 30, as VIA)")
    _add_gen_pilot(kinds)
    p.set_defaults(func=_run_gen)


def _add_gen_pilot(kinds) -> None:
    pilot = kinds.add_parser("pilot", help="teacher drives for the end-to-end pilot (recordings)",
                             description="Many short drives of signlane's own driver (the teacher) in the local "
                                         "simulator, lockstep, one per procedural seed and road style, each "
                                         "recorded as `signlane sim --record` does (images/, drive.jsonl with the "
                                         "teacher's command, lane estimate, state and desire; manifest.json with "
                                         "track, style and looks) under OUT/drives/<style>-seed<N>/. The applied "
                                         "steering is perturbed by smooth pulses (--perturb) so the drives show "
                                         "the teacher steering back; the label stays its own command. Seeds "
                                         "0-19 are the closed-loop acceptance's: train on others (default 1000+).")
    pilot.add_argument("--n", type=positive, required=True, help="seeds (drives per style)")
    pilot.add_argument("--out", type=Path, required=True, help="output folder")
    pilot.add_argument("--first-seed", type=int, default=1000, help="first procedural seed (default 1000)")
    pilot.add_argument("--style", nargs="+", choices=["via", "painted"], default=["via", "painted"],
                       help="road styles, a drive of each seed in each (default both)")
    pilot.add_argument("--seconds", type=float, default=30.0, help="simulated seconds per drive (default 30)")
    pilot.add_argument("--perturb", type=float, default=0.3,
                       help="peak steering of the perturbation pulses, 0..1 (default 0.3; 0 = none)")
    pilot.add_argument("--every", type=positive, default=2, help="keep every N-th frame (default 2)")
    pilot.add_argument("--looks", choices=["default", "random", "mixed"], default="mixed",
                       help="scenery colours: the default ones, random (seeded), or mixed: every other seed "
                            "random (default)")
    pilot.add_argument("--student", type=Path, default=None,
                       help="DAgger: a pilot ONNX file steers each drive instead of the teacher, which labels "
                            "every frame and takes the wheel for a second where they disagree (--takeover); "
                            "use --perturb 0 and train on these drives together with the teacher's")
    pilot.add_argument("--takeover", type=float, default=0.25,
                       help="with --student: the steering difference at which the teacher takes over (default 0.25)")
    pilot.add_argument("--workers", type=positive, default=1, help="worker processes, a drive each (default 1)")
    pilot.add_argument("--resume", action="store_true", help="complete an interrupted run in --out")


def _run_gen(args) -> int:
    from signlane_data.common import DatasetError
    try:
        return _gen(args)
    except (DatasetError, ValueError) as e:  # the generators' checks of their options: one line
        raise UserError(str(e)) from None


def _gen(args) -> int:
    if args.kind == "lanes":
        from signlane_data.lanes import generate_lanes
        m = generate_lanes(args.out, args.n, args.seed, width=args.size[0], height=args.size[1],
                           workers=args.workers, resume=args.resume, preview=args.preview,
                           effects=args.effects, randomise=args.randomise, drivable=args.drivable,
                           preset=args.preset, style=args.style or "painted", junctions=args.junctions)
    elif args.kind == "signs":
        from signlane_data.signs import generate_signs
        m = generate_signs(args.out, args.n, args.seed, crop=args.crop, workers=args.workers,
                           resume=args.resume, preview=args.preview, style=args.style or "painted")
    elif args.kind == "pilot":
        from signlane.onnx_model import ModelError
        from signlane_data.pilot import generate_pilot_drives
        try:
            m = generate_pilot_drives(args.out, args.n, args.first_seed, tuple(args.style), args.seconds,
                                      args.perturb, args.every, args.looks, workers=args.workers, resume=args.resume,
                                      student=args.student or "", takeover=args.takeover)
        except (ValueError, ModelError) as e:
            raise UserError(str(e)) from None
    else:
        from signlane_data.drive import generate_drive
        m = generate_drive(args.out, args.n, args.seed, width=args.size[0], height=args.size[1], fps=args.fps,
                           resume=args.resume, preview=args.preview, style=args.style or "via")
    print(json.dumps({"out": str(args.out), "counts": m.get("counts")}))
    return 0


# --- demo --------------------------------------------------------------------------------------
def add_demo(sub) -> None:
    p = sub.add_parser("demo", help="a closed-loop drive in the local simulator: video, path and score",
                       description="Drive the car closed-loop in the local simulator on a bundled map with signs "
                                   "(default via_town, in VIA's look), in lockstep, with signlane's driver and the shipped "
                                   "models: writes drive.mp4 (what the driver saw and did), path.png (the driven "
                                   "path from above), report.json, and prints the score table.")
    p.add_argument("--out", type=Path, default=Path("out/demo"), help="output folder (default out/demo)")
    p.add_argument("--track", default="via_town",
                   help="a bundled map (via_town, loop_demo), 'random' (procedural, see --seed) or a VIA map JSON file")
    p.add_argument("--style", choices=["via", "painted"], default="via",
                   help="how roads look: VIA's kerbed carriageway (default) or painted lanes")
    p.add_argument("--seed", type=int, default=0, help="seed of a random track (default 0)")
    p.add_argument("--laps", type=positive, default=1, help="laps to drive (default 1)")
    p.add_argument("--max-seconds", type=float, default=600.0,
                   help="stop after this much simulated time, laps done or not (default 600)")
    p.add_argument("--size", type=size_arg, default=(640, 480), help="frame size WxH (default 640x480)")
    p.add_argument("--lanes", help="lane method (default from the config)")
    p.set_defaults(func=_run_demo)


def _run_demo(args) -> int:
    from signlane.commands.sim import track_arg
    from signlane.config import Config
    from signlane.demo import run_demo
    from signlane.sim.score import format_report
    track = track_arg(args.track, args.style, args.seed)
    try:
        config = Config.load(None, [f"lanes.method={args.lanes}"] if args.lanes else [])
    except ValueError as e:
        raise UserError(str(e)) from None
    if not args.max_seconds > 0:
        raise UserError(f"--max-seconds must be > 0, not {args.max_seconds:g}")
    rep = run_demo(args.out, track=track, laps=args.laps, width=args.size[0], height=args.size[1], config=config,
                   max_seconds=args.max_seconds)
    print(format_report(rep))
    for name, path in rep["files"].items():
        print(f"{name:>8}: {path}")
    return 0


# --- map ---------------------------------------------------------------------------------------
def add_map(sub) -> None:
    p = sub.add_parser("map", help="check a VIA map file, or make a procedural one; draw it from above",
                       description="Load a VIA map JSON as VIA's editor writes it (or generate a seeded procedural "
                                   "map in the same format), report what VIA would draw oddly (dead ends, unknown "
                                   "tiles, overlaps), print a summary and optionally write a top-down PNG drawn the "
                                   "way VIA's minimap is (25 pixels a cell, north up) and the map JSON.")
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("file", nargs="?", type=Path, help="VIA map JSON file")
    src.add_argument("--random", type=int, metavar="SEED", help="generate a procedural map with this seed")
    p.add_argument("--size", choices=["small", "medium", "large"], default="medium",
                   help="procedural map size (default medium)")
    p.add_argument("--style", choices=["via", "painted"], default="via",
                   help="road style to draw (default via: VIA's kerbed carriageway)")
    p.add_argument("--png", type=Path, help="write a top-down picture here (with the lap from the start in red)")
    p.add_argument("--save", type=Path, help="write the map JSON here (for --random)")
    p.set_defaults(func=_run_map)


def _run_map(args) -> int:
    from signlane.draw import write_image
    from signlane.fileio import atomic_write_json
    import numpy as np
    from signlane.world.procedural import generate_map
    from signlane.world.route import Route
    from signlane.world.scene import build_scene
    from signlane.world.topdown import draw_topdown
    from signlane.world.track import MapError, RoadStyle, Track, read_map
    style = RoadStyle.named(args.style)
    try:
        if args.file is not None:
            track = Track.from_via(read_map(args.file), style=style, source=str(args.file))
            data = None
        else:
            data = generate_map(args.random, size=args.size)
            track = Track.from_via(data, style=style)
    except MapError as e:
        raise UserError(str(e)) from None
    kinds: dict[str, int] = {}
    for t in track.tiles:
        kinds[t.name] = kinds.get(t.name, 0) + 1
    try:
        lap = Route.loop(track)
        lap_m, path = round(lap.length, 1), lap.lane
    except RuntimeError as e:  # no loop from the start (a dead end first): still a map VIA draws
        lap_m, path = str(e), None
    print(json.dumps({"name": track.name, "grid": [track.cols, track.rows], "tiles": kinds,
                      "signs": [s.kind for s in track.signs], "dead_ends": len(track.dead_ends),
                      "lap_m": lap_m, "warnings": track.warnings}))
    if args.png:
        # (the lap is the cycle the road from the start falls into: the car may start before it)
        write_image(args.png, draw_topdown(build_scene(track), path_xy=path, legend="lap from the start",
                                           start_xy=np.asarray(track.start_state()[3], float)))
    if args.save and data is not None:
        atomic_write_json(args.save, data)
    return 0

