"""`signlane sim`: the local VIA-compatible simulator (a WebSocket client of a drive server)."""
from __future__ import annotations

import argparse
import math
from pathlib import Path

from signlane.commands.common import UserError, add_serve_args, positive, size_arg


def fps_arg(text: str) -> float:
    """--fps: a positive number, or `uncapped` / 0 for as fast as frames can be made."""
    if text.strip().lower() == "uncapped":
        return 0.0
    try:
        v = float(text)
    except ValueError:
        v = math.nan
    if not (v == 0 or (math.isfinite(v) and v > 0)):
        raise argparse.ArgumentTypeError(f"must be a positive number of frames/s or 'uncapped', not {text!r}")
    return v


def add_sim(sub) -> None:
    p = sub.add_parser("sim", help="drive a car in the local simulator and score the drive",
                       description="signlane's own VIA-compatible simulator: renders the camera view at the "
                                   "car's pose (640x480 JPEG of quality 75 by default) and sends it to a drive "
                                   "server exactly as VIA does (binary WebSocket frames of JSON with N4 number "
                                   "strings, speed in mph, the image one frame behind the numbers). The car is "
                                   "VIA's: steering 1.0 = 25 degrees, set at once; throttle is a target fraction "
                                   "of 30 mph (13.41 m/s), held by half pedal (1.4 m/s^2) while below it; no "
                                   "brakes and no reverse, so throttle 0 coasts (drag and rolling resistance); "
                                   "with no new reply the last steering and pedal stay. It scores the drive: "
                                   "laps, autonomy, off-road events, cross-track error, stop and turn compliance.")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--map", type=Path, help="a VIA map JSON file, as VIA's editor writes them "
                                                "(default: the bundled via_town)")
    where.add_argument("--track", help="a bundled map (via_town, loop_demo) or 'random': a seeded procedural "
                                       "track with junctions and signs (see --seed)")
    p.add_argument("--style", choices=["via", "painted"], default="via",
                   help="how roads look: via = VIA's own (one 4 m carriageway between white kerbs, no paint; "
                        "default), painted = two painted lanes on wider cells")
    p.add_argument("--seed", type=int, default=0, help="procedural track seed (default 0)")
    p.add_argument("--url", help="drive server to connect to (default ws://127.0.0.1:4567)")
    p.add_argument("--with-driver", action="store_true",
                   help="start signlane's drive server in this process on a free port and drive with it")
    p.add_argument("--lockstep", action="store_true",
                   help="wait for each answer before the next frame (deterministic) and add a \"time\" key "
                        "(simulated seconds) to each frame so the server can keep simulated time; VIA does "
                        "neither. Default: real time, VIA's exact messages, never waiting for an answer")
    p.add_argument("--fps", type=fps_arg, default=30.0, metavar="FPS|uncapped",
                   help="frames per second (default 30; e.g. 60): in lockstep each frame is 1/FPS simulated "
                        "seconds, in real time frames go out at this rate; 'uncapped' or 0: as fast as frames "
                        "can be made, as VIA's native build, each frame's time step the wall time since the "
                        "last (at most 0.1 s)")
    p.add_argument("--decimal", choices=[".", ","], default=".",
                   help="decimal mark of the numbers sent: ',' as VIA on a comma-decimal machine (\"0,5000\"; "
                        "default '.')")
    p.add_argument("--size", type=size_arg, default=(640, 480), help="camera frame WxH (default 640x480)")
    p.add_argument("--laps", type=positive, default=1, help="stop after this many laps (default 1)")
    p.add_argument("--max-seconds", type=float, default=600.0, help="stop after this much simulated time (default 600)")
    p.add_argument("--effects", choices=["clean", "normal", "hard"], default="clean",
                   help="camera effects (default clean)")
    p.add_argument("--random-looks", action="store_true", help="randomise road and scenery colours (seeded)")
    p.add_argument("--report", type=Path, help="write the score as JSON here")
    p.add_argument("--out", type=Path, help="folder for report.json, path.png (top-down driven path)"
                                             " and, with --video, drive.mp4")
    p.add_argument("--video", action="store_true",
                   help="with --out: drive.mp4 (H.264), the frames with the command and, with --with-driver, what "
                        "the driver saw (lanes, sign boxes, state), as `demo` draws it")
    p.add_argument("--record", type=Path, metavar="DIR",
                   help="record the drive for learning from it (`signlane train pilot`): images/<id>.jpg, "
                        "drive.jsonl (telemetry, the command, the teacher's command, lane estimate, state, "
                        "desire) and manifest.json (track, style, looks), the layout `signlane drive --record` "
                        "writes; by the in-process driver, or with --with-driver by its server")
    p.add_argument("--perturb", type=float, default=0.0, metavar="SCALE",
                   help="with --record, in-process: add smooth steering pulses of up to SCALE (e.g. 0.3) to "
                        "the applied steering, so the recording shows the teacher steering back to the lane "
                        "centre; the label stays the teacher's own command (default 0: none)")
    p.add_argument("--record-every", type=positive, default=1, metavar="N",
                   help="with --record: keep every N-th frame (default 1; neighbouring frames look alike)")
    add_serve_args(p, 0, "the drive server", when="with --with-driver: ")
    p.add_argument("--lanes", help="lane method for --with-driver (default from the config)")
    p.add_argument("--no-signs", action="store_true", help="--with-driver without the sign stage")
    p.add_argument("--config", type=Path, help="TOML config for --with-driver")
    p.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE", help="config override")
    p.set_defaults(func=_run_sim)


def track_arg(spec, style: str, seed: int):
    """The track a command names (bundled, random or a file), or one UserError line."""
    from signlane.world.maps import load_track
    try:
        return load_track(spec, style, seed)
    except ValueError as e:  # MapError included
        raise UserError(str(e)) from None


def _run_sim(args) -> int:
    from signlane.config import Config
    from signlane.sim.score import format_report
    from signlane.sim.session import run_session
    from signlane.sim.simulator import SimConfig
    track = track_arg(args.map or args.track or "via_town", args.style, args.seed)
    sets = list(args.set) + ([f"lanes.method={args.lanes}"] if args.lanes else [])
    sets += ["signs.enabled=false"] if args.no_signs else []
    try:
        config = Config.load(args.config, sets)
    except ValueError as e:
        raise UserError(str(e)) from None
    sim_cfg = SimConfig(width=args.size[0], height=args.size[1], fps=args.fps, effects=args.effects,
                        random_looks=args.random_looks, looks_seed=args.seed, laps=args.laps,
                        max_seconds=args.max_seconds, decimal=args.decimal)
    # --record without --with-driver: signlane's own driver, in this process and in lockstep (the teacher)
    inprocess = args.record is not None and not args.with_driver and args.url is None
    url = None if args.with_driver or inprocess else (args.url or "ws://127.0.0.1:4567")
    from signlane.sim.server import ServerOptions
    options = ServerOptions(host=args.host, port=args.port, web=not args.no_web, allow_control=args.allow_control)
    if args.with_driver and not args.no_web:
        from signlane.drive.web import warn_if_exposed
        warn_if_exposed(args.host, "the drive server and its monitor")
    from signlane.onnx_model import ModelError
    from signlane.sim.drive_record import RecordError
    from signlane.sim.driver import SignStageError
    noise = None
    if args.perturb:
        if not (math.isfinite(args.perturb) and 0 < args.perturb <= 1) or not args.record:
            raise UserError(f"--perturb {args.perturb}: needs --record and a scale in (0, 1]")
        from signlane.sim.teacher import NoiseParams, SteeringNoise
        noise = SteeringNoise(NoiseParams(scale=args.perturb), args.seed)
    try:
        rep = run_session(track, sim_cfg, args.out, config, url=url, lockstep=args.lockstep or inprocess,
                          with_driver=args.with_driver, video=args.video, server_options=options,
                          record=args.record, noise=noise, record_every=args.record_every)
    except RecordError as e:
        raise UserError(str(e)) from None
    except (ModelError, SignStageError, ValueError) as e:  # the driver cannot be built: as `drive` says it
        raise UserError(str(e)) from None
    except OSError as e:
        if args.with_driver:  # our own server could not listen
            raise UserError(f"cannot serve on {args.host}:{args.port}: {e.strerror or e}") from None
        raise UserError(f"cannot reach the drive server at {url} ({e}); start one with `signlane drive` "
                        "or use --with-driver") from None
    print(format_report(rep))
    if args.report:
        from signlane.fileio import atomic_write_json
        atomic_write_json(args.report, rep)
    if args.out:
        print(f"report: {args.out / 'report.json'}\npath:   {args.out / 'path.png'}")
    return 0
