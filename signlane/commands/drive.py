"""`signlane drive`: the VIA-protocol drive server; `signlane export-drive`: its recordings for other tools."""
from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

from signlane.commands.common import UserError, pixels_arg, positive, size_arg
from signlane.commands.common import add_config_args, add_serve_args, load_config


def add_drive(sub) -> None:
    p = sub.add_parser(
        "drive", help="drive the VIA simulator (or `signlane sim`): a WebSocket server on 127.0.0.1:4567",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Serve the VIA simulator's protocol: the simulator connects and sends one binary frame\n"
                    "of UTF-8 JSON per rendered image ({\"steering_angle\": wheel degrees, \"throttle\": the\n"
                    "pedal applied, \"speed\": mph, \"image\": base64 JPEG}, every value an N4 string such as\n"
                    "\"0.5000\" or \"0,5000\"; text frames are accepted too) and gets {\"throttle\", \"steering\"}\n"
                    "back as text for every frame: steering in [-1, 1] (1 = 25 degrees right), throttle a target\n"
                    "fraction of 30 mph that VIA holds at half pedal (no brakes: above its target the car coasts).\n"
                    "Each connection has its own driver (lane method + signs + controller). Frames that arrive\n"
                    "while the driver is still busy are answered at once with the latest command, so the car\n"
                    "never acts on a backlog. A bad frame gets one log line and a safe answer (coast, wheels\n"
                    "straight); the server keeps serving. Rates and latencies are logged every --log-every\n"
                    "seconds.\n\n"
                    "The same host and port serve a live monitor page (http://127.0.0.1:4567/, also VIA's\n"
                    "/web/index.html): the camera with lanes, sign boxes and state, other topics (lane mask,\n"
                    "bird's-eye, colour masks, edges), plots of steering, speed and latency. It only reads:\n"
                    "--allow-control lets a viewer save frames; --no-web turns it off.\n\n"
                    "examples:\n"
                    "  signlane drive                                # then start the simulator\n"
                    "  signlane drive --lanes canny-scan --no-signs\n"
                    "  signlane drive --record runs/drive1 --show-every 20 --show-dir runs/drive1_frames")
    add_serve_args(p, 4567, "the drive server")
    p.add_argument("--lanes", metavar="METHOD",
                   help="lane method: auto (default: road-edges on a kerbed carriageway such as VIA's, "
                        "sliding-window on painted lanes), road-edges, sliding-window, canny-scan, color-hough, "
                        "vector-spline, segnet")
    p.add_argument("--signs", action=argparse.BooleanOptionalAction, default=None,
                   help="traffic-sign detection (default from config: on)")
    p.add_argument("--sync-signs", action="store_true",
                   help="classify signs in step with every frame (deterministic, for lockstep simulators); "
                        "default: beside the lane path, so signs never delay steering")
    p.add_argument("--record", type=Path, metavar="DIR",
                   help="record a driving dataset: images/<id>.jpg, drive.jsonl (telemetry, command, lane, "
                        "signs per frame), manifest.json on exit. DIR must be new or empty")
    p.add_argument("--show-every", type=positive, metavar="N",
                   help="write every N-th driven frame annotated (lane, signs, steering/throttle/state)")
    p.add_argument("--show-dir", type=Path, default=Path("drive_frames"), metavar="DIR",
                   help="folder for --show-every frames (default drive_frames/)")
    p.add_argument("--max-bytes", type=positive, default=8 * 1024 * 1024, metavar="N",
                   help="largest frame message accepted, bytes (default 8 MB); larger ones get the safe answer, "
                        "and ones over twice this close the connection")
    p.add_argument("--max-pixels", type=pixels_arg, default=4096 * 4096, metavar="WxH",
                   help="largest image accepted, read from its header before decoding (default 4096x4096); "
                        "larger ones get the safe answer")
    p.add_argument("--log-every", type=float, default=10.0, metavar="SEC",
                   help="seconds between rate/latency log lines (default 10)")
    add_config_args(p)
    p.set_defaults(func=_run_drive)


def _run_drive(args) -> int:
    from signlane.onnx_model import ModelError
    from signlane.sim.drive_record import RecordError
    from signlane.sim.driver import SignStageError
    from signlane.sim.server import ServerOptions, run_server
    cfg = load_config(args)
    if args.signs is not None:
        cfg = replace(cfg, signs=replace(cfg.signs, enabled=args.signs))
    if args.log_every <= 0:
        raise UserError(f"--log-every must be > 0, not {args.log_every}")
    options = ServerOptions(host=args.host, port=args.port, max_bytes=args.max_bytes, max_pixels=args.max_pixels,
                            record=args.record, show_every=args.show_every or 0, show_dir=args.show_dir,
                            sync_signs=args.sync_signs, log_every_s=args.log_every, web=not args.no_web,
                            allow_control=args.allow_control)
    from signlane.drive.web import warn_if_exposed
    warn_if_exposed(args.host, "the drive server" + ("" if args.no_web else " and its monitor"))
    try:
        run_server(cfg, options)
    except (RecordError, ModelError, SignStageError, ValueError) as e:
        raise UserError(str(e)) from None
    except OSError as e:  # the port is taken, the address is not ours, ...
        raise UserError(f"cannot serve on {args.host}:{args.port}: {e.strerror or e}") from None
    return 0


def add_export_drive(sub) -> None:
    p = sub.add_parser(
        "export-drive", help="export a `drive --record` recording for other tools (a Donkey Car tub)",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Write a drive recording (`signlane drive --record DIR`: images/, drive.jsonl, manifest.json)\n"
                    "in another tool's format. One format for now:\n\n"
                    "  tub   Donkey Car's tub (donkeycar 4.x/5.x Tub, datastore v2), which `donkey train` reads:\n"
                    "        images/<index>_cam_image_array_.jpg, catalog_<n>.catalog (one JSON record per line,\n"
                    "        1000 a file) with catalog_<n>.catalog_manifest, and manifest.json. Each frame is\n"
                    "        one record: cam/image_array (the JPEG as the simulator sent it, or resized with\n"
                    "        --size), user/angle and user/throttle (the command the driver sent: steering in\n"
                    "        [-1, 1], positive right; throttle in [0, 1]), user/mode \"user\" and car/speed\n"
                    "        (m/s). Each connection of the recording is one session.\n\n"
                    "The recording must be complete (manifest.json is written last, on a clean exit). The\n"
                    "output is built beside --out and renamed into place, so it is never left half written.\n\n"
                    "examples:\n"
                    "  signlane export-drive runs/drive1 --out data/tub1\n"
                    "  signlane export-drive runs/drive1 --out data/tub1 --size 160x120 --force   # donkeycar's default size")
    p.add_argument("recording", type=Path, help="a recording folder written by `signlane drive --record`")
    p.add_argument("--out", type=Path, required=True, help="output folder (new or empty, unless --force)")
    p.add_argument("--format", choices=["tub"], default="tub", help="output format (default tub: Donkey Car's)")
    p.add_argument("--size", type=size_arg, metavar="WxH",
                   help="resize every image to WxH (e.g. 160x120, donkeycar's default camera size); "
                        "default: the recorded JPEG bytes, not re-encoded")
    p.add_argument("--force", action="store_true", help="replace a non-empty --out folder")
    p.set_defaults(func=_run_export_drive)


def _run_export_drive(args) -> int:
    from signlane.sim.drive_record import RecordError
    from signlane.tub import TubError, export_drive_tub
    try:
        done = export_drive_tub(args.recording, args.out, size=args.size, force=args.force)
    except (RecordError, TubError) as e:
        raise UserError(str(e)) from None
    except OSError as e:
        raise UserError(f"{args.out}: cannot write the tub ({e.strerror or e})") from None
    print(f"wrote {done.frames} frames ({done.sessions} session(s), {done.catalogs} catalog file(s)) "
          f"as a Donkey Car tub in {done.folder}")
    return 0
