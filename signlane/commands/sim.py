"""`signlane sim`: the local VIA-compatible simulator (a WebSocket client of a drive server)."""
from __future__ import annotations

from pathlib import Path

from signlane.commands.common import UserError, positive, size_arg


def add_sim(sub) -> None:
    p = sub.add_parser("sim", help="drive a car in the local simulator and score the drive",
                       description="signlane's own VIA-compatible simulator: renders the camera view at the "
                                   "car's pose (640x480 JPEG by default), sends it to a drive server in VIA's "
                                   "protocol, moves the car with a kinematic bicycle model (steering scaled to "
                                   "25 degrees, throttle a target speed fraction) and scores the drive: laps, "
                                   "autonomy, off-road events, cross-track error, stop and turn compliance.")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--map", type=Path, help="a VIA map JSON file (default: the bundled loop_demo)")
    where.add_argument("--track", choices=["random"], help="a seeded procedural track with junctions and signs")
    p.add_argument("--seed", type=int, default=0, help="procedural track seed (default 0)")
    p.add_argument("--url", default="ws://127.0.0.1:4567", help="drive server to connect to (default %(default)s)")
    p.add_argument("--with-driver", action="store_true",
                   help="start signlane's drive server in this process on a free port and drive with it")
    p.add_argument("--lockstep", action="store_true",
                   help="wait for each answer before the next frame (deterministic; default: real time, the "
                        "simulator never waits, as VIA)")
    p.add_argument("--fps", type=float, default=20.0, help="frames per second of simulated time (default 20)")
    p.add_argument("--size", type=size_arg, default=(640, 480), help="camera frame WxH (default 640x480)")
    p.add_argument("--laps", type=positive, default=1, help="stop after this many laps (default 1)")
    p.add_argument("--max-seconds", type=float, default=600.0, help="stop after this much simulated time (default 600)")
    p.add_argument("--effects", choices=["clean", "normal", "hard"], default="clean",
                   help="camera effects (default clean)")
    p.add_argument("--random-looks", action="store_true", help="randomise road and scenery colours (seeded)")
    p.add_argument("--report", type=Path, help="write the score as JSON here")
    p.add_argument("--out", type=Path, help="folder for report.json, path.png (top-down driven path)"
                                             " and, with --video, drive.mp4")
    p.add_argument("--video", action="store_true", help="with --out: drive.mp4, the frames with the command (and, in process, what the driver saw)")
    p.add_argument("--lanes", help="lane method for --with-driver (default from the config)")
    p.add_argument("--no-signs", action="store_true", help="--with-driver without the sign stage")
    p.add_argument("--config", type=Path, help="TOML config for --with-driver")
    p.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE", help="config override")
    p.set_defaults(func=_run_sim)


def load_track(map_path: Path | None, random: bool, seed: int):
    from signlane.demo import bundled_map
    from signlane.world.procedural import generate_map
    from signlane.world.track import MapError, Track
    try:
        if random:
            return Track.from_via(generate_map(seed))
        return Track.load(map_path) if map_path else bundled_map()
    except MapError as e:
        raise UserError(str(e)) from None


def _run_sim(args) -> int:
    from signlane.config import Config
    from signlane.sim.score import format_report
    from signlane.sim.session import run_session
    from signlane.sim.simulator import SimConfig
    track = load_track(args.map, args.track == "random", args.seed)
    sets = list(args.set) + ([f"lanes.method={args.lanes}"] if args.lanes else [])
    sets += ["signs.enabled=false"] if args.no_signs else []
    try:
        config = Config.load(args.config, sets)
    except ValueError as e:
        raise UserError(str(e)) from None
    sim_cfg = SimConfig(width=args.size[0], height=args.size[1], fps=args.fps, effects=args.effects,
                        random_looks=args.random_looks, looks_seed=args.seed, laps=args.laps,
                        max_seconds=args.max_seconds)
    url = None if args.with_driver else args.url
    from signlane.onnx_model import ModelError
    from signlane.sim.driver import SignStageError
    try:
        rep = run_session(track, sim_cfg, args.out, config, url=url, lockstep=args.lockstep,
                          with_driver=args.with_driver, video=args.video)
    except (ModelError, SignStageError, ValueError) as e:  # the driver cannot be built: as `drive` says it
        raise UserError(str(e)) from None
    except OSError as e:
        raise UserError(f"cannot reach the drive server at {args.url} ({e}); start one with `signlane drive` "
                        "or use --with-driver") from None
    print(format_report(rep))
    if args.report:
        from signlane.fileio import atomic_write_json
        atomic_write_json(args.report, rep)
    if args.out:
        print(f"report: {args.out / 'report.json'}\npath:   {args.out / 'path.png'}")
    return 0
