"""Pieces every subcommand module shares: the one-line user error and argument types."""
from __future__ import annotations

import argparse
from pathlib import Path


class UserError(Exception):
    """A problem with the user's input: printed as one line, exit code 2."""


def size_arg(text: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
        if w < 16 or h < 16:
            raise ValueError
        return w, h
    except ValueError:
        raise argparse.ArgumentTypeError(f"size must look like 320x240 (both >= 16), not {text!r}") from None


def positive(text: str) -> int:
    v = int(text)
    if v < 1:
        raise argparse.ArgumentTypeError(f"must be >= 1, not {v}")
    return v


def pixels_arg(text: str) -> int:
    """A pixel limit: WxH (4096x4096) or a plain count of pixels."""
    try:
        parts = [int(v) for v in text.lower().split("x")]
        if len(parts) not in (1, 2) or min(parts) < 16:
            raise ValueError
        return parts[0] * parts[-1] if len(parts) == 2 else parts[0]
    except ValueError:
        raise argparse.ArgumentTypeError(f"pixel limit must look like 4096x4096 or 16777216, not {text!r}") from None


def port_arg(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        v = -1
    if not 0 <= v <= 65535:
        raise argparse.ArgumentTypeError(f"must be a port 0..65535, not {text!r}")
    return v


def add_serve_args(p, port: int, what: str, when: str = "") -> None:
    """--host, --port, --no-web and --allow-control of a command that serves `what` (and the
    monitor page beside it); `when`: the option they need, if any (e.g. "with --with-driver: ")."""
    p.add_argument("--host", default="127.0.0.1",
                   help=f"{when}{what}'s address (default 127.0.0.1; anything else opens it to the network, "
                        "with a warning)")
    free = "0: any free port; the log says which" if port == 0 else f"{port}; 0 = any free"
    p.add_argument("--port", type=port_arg, default=port, help=f"{when}{what}'s port (default {free})")
    p.add_argument("--no-web", action="store_true",
                   help=f"{when}no monitor page (default: http://HOST:PORT/ shows what the driver sees, live)")
    p.add_argument("--allow-control", action="store_true",
                   help=f"{when}let monitor viewers save the current frame and its state (monitor_snapshots/); "
                        "without it no page or endpoint writes anything or changes a setting")


def add_config_args(p, config_help: str = "TOML config file (sections camera, lanes, signs, control)") -> None:
    """--config FILE and repeatable --set SECTION.KEY=VALUE, read by load_config."""
    p.add_argument("--config", type=Path, help=config_help)
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="SECTION.KEY=VALUE",
                   help="override one setting, e.g. --set camera.pitch_deg=12 (repeatable)")


def load_config(args):
    """The Config of add_config_args' options (and of --lanes, where the command has one); a bad
    file or setting is one UserError line."""
    from signlane.config import Config
    try:
        cfg = Config.load(args.config, args.overrides)
    except ValueError as e:
        raise UserError(str(e)) from None
    lanes_method = getattr(args, "lanes", None)
    if lanes_method:
        from dataclasses import replace
        cfg = replace(cfg, lanes=replace(cfg.lanes, method=lanes_method))
    return cfg
