"""Pieces every subcommand module shares: the one-line user error and argument types."""
from __future__ import annotations

import argparse


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
