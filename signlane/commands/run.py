"""`signlane run`: drive a car from a camera or a video, commands to an actuator, with the monitor."""
from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

from signlane.commands.common import UserError, add_config_args, add_serve_args, load_config


def _fraction(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        v = float("nan")
    if not 0 < v <= 1:
        raise argparse.ArgumentTypeError(f"must be a number in (0, 1] (1 = no smoothing), not {text!r}")
    return v


def _seconds(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        v = float("nan")
    if not 0 < v < 3600:
        raise argparse.ArgumentTypeError(f"must be a number of seconds > 0, not {text!r}")
    return v


def add_run(sub) -> None:
    p = sub.add_parser(
        "run", help="drive from a camera or a video file: commands to your car's actuator, a live monitor page",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Run the drive stack (lanes, junctions, signs, behaviour: what `signlane drive` runs for VIA)\n"
                    "on a camera or a video and send every command to an actuator.\n\n"
                    "sources:\n"
                    "  --camera 0          an OpenCV VideoCapture device index, or a URL / pipeline string\n"
                    "                      (rtsp://..., http://.../video.mjpg)\n"
                    "  --video FILE        a video file played at its own frame rate (frames the driver has no\n"
                    "                      time for are dropped, as a camera's would be)\n"
                    "actuators (--actuator):\n"
                    "  print               one JSON line per command on stdout:\n"
                    "                      {\"t\": s, \"steering\": -1..1 (+ right), \"throttle\": 0..1, \"state\": str}\n"
                    "  udp:HOST:PORT       the same JSON object as one UDP datagram per command\n"
                    "  module:Class        your motor driver: a class (importable from here or the Python path)\n"
                    "                      built with no arguments, with step(command) and close(); command has\n"
                    "                      .steering, .throttle (a target fraction of drive.max_speed) and .state\n\n"
                    "Safety: the car gets throttle 0 with wheels straight (state \"stop: <why>\") when no frame\n"
                    "arrives for --frame-timeout seconds (it drives on when frames come back), when a frame\n"
                    "cannot be driven, and always last: at the end of the video, on Ctrl-C or SIGTERM.\n"
                    "A camera reports no speed: the driver takes the car to hold the speed it was last asked for.\n\n"
                    "The monitor (unless --no-web): http://127.0.0.1:4567/ shows the camera with lanes, sign\n"
                    "boxes and state, other topics (lane mask, bird's-eye, colour masks, edges) and live plots.\n"
                    "It only reads; --allow-control lets a viewer save the current frame.\n\n"
                    "examples:\n"
                    "  signlane run --camera 0 --actuator udp:192.168.4.1:9000\n"
                    "  signlane run --video out/demo/drive.mp4 --actuator print --no-web\n"
                    "  signlane run --camera 0 --actuator mycar:Motors --set drive.cruise_speed=1.5")
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--camera", metavar="INDEX|URL", help="camera: VideoCapture index (0) or URL")
    src.add_argument("--video", type=Path, metavar="FILE", help="video file, played at its own frame rate")
    p.add_argument("--actuator", default="print", metavar="SPEC",
                   help="print (default), udp:HOST:PORT or module:Class (see above)")
    p.add_argument("--smoothing", type=_fraction, metavar="A",
                   help="steering smoothing, the weight of each new value in (0, 1]: 1 = off "
                        "(default 0.5 for a camera, off for a video)")
    p.add_argument("--frame-timeout", type=_seconds, default=1.0, metavar="SEC",
                   help="stop the car when no frame arrives for this long (default 1.0)")
    p.add_argument("--lanes", metavar="METHOD", help="lane method (default from the config: auto)")
    p.add_argument("--signs", action=argparse.BooleanOptionalAction, default=None,
                   help="traffic-sign detection (default from config: on)")
    p.add_argument("--sync-signs", action=argparse.BooleanOptionalAction, default=None,
                   help="classify signs in step with every frame (default for --video) rather than beside the "
                        "lane path (default for --camera, so signs never delay steering)")
    add_serve_args(p, 4567, "the monitor")
    add_config_args(p)
    p.set_defaults(func=_run)


def _run(args) -> int:
    import logging
    import signal
    import threading
    from signlane.drive.actuators import ActuatorError, load_actuator
    from signlane.drive.run import run_loop
    from signlane.drive.sources import CameraSource, SourceError, VideoSource
    from signlane.drive.stack import DriveStack
    from signlane.drive.signs import SignStageError
    from signlane.onnx_model import ModelError
    log = logging.getLogger("signlane.run")
    cfg = load_config(args)
    if args.signs is not None:
        cfg = replace(cfg, signs=replace(cfg.signs, enabled=args.signs))
    camera = args.camera is not None
    smoothing = args.smoothing if args.smoothing is not None else (0.5 if camera else 1.0)
    sync = args.sync_signs if args.sync_signs is not None else not camera
    try:
        source = CameraSource(args.camera) if camera else VideoSource(args.video)
        actuator = load_actuator(args.actuator)
    except (SourceError, ActuatorError) as e:
        raise UserError(str(e)) from None
    try:
        stack = DriveStack(cfg, sync_signs=sync)
        probe(stack)  # a bad model or method fails before anything moves
    except (ModelError, ValueError, OSError, SignStageError) as e:
        actuator.close()
        source.close()
        raise UserError(str(e)) from None
    monitor = server = None
    if not args.no_web:
        from signlane.drive.monitor import Monitor
        from signlane.drive.monitor_server import MonitorServer
        from signlane.drive.web import warn_if_exposed
        warn_if_exposed(args.host, "the monitor")
        monitor = Monitor(cfg.camera)
        try:
            server = MonitorServer(monitor, args.host, args.port, args.allow_control).start()
        except OSError as e:
            stack.close()
            actuator.close()
            raise UserError(f"monitor: cannot serve on {args.host}:{args.port}: {e.strerror or e} "
                            "(another port with --port, or --no-web)") from None
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    source.start()
    try:
        totals = run_loop(source, stack, actuator, monitor, smoothing, args.frame_timeout, stop)
        log.info("%s", totals.summary(source.frames_read))
    finally:
        stack.close()
        if server is not None:
            server.close()
        if monitor is not None:
            monitor.close()
    return 0


def probe(stack) -> None:
    """Drive one grey frame and forget it: models load on the first frame, so a missing or broken
    one is reported before the car moves."""
    import logging
    import numpy as np
    from signlane.drive.signs import SignStageError
    from signlane.onnx_model import ModelError
    try:
        stack.drive(np.full((240, 320, 3), 110, np.uint8), 0.0, 0.0, 0.0)
    except (ModelError, ValueError, OSError, SignStageError):
        raise
    except Exception as e:  # a driver bug on a blank frame: worth a line, not a refusal to drive
        logging.getLogger("signlane.run").warning("the driver failed on a blank test frame: %s: %s",
                                                  type(e).__name__, e)
    stack.reset()
