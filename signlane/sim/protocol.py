"""The VIA simulator's WebSocket protocol: telemetry (simulator -> server) and commands (server -> simulator).

Telemetry is one JSON text message per frame whose values are all strings, numbers with 4
decimals: `{"steering_angle": "-3.1416", "throttle": "0.5000", "speed": "7.2500",
"image": "<base64 JPEG>"}`. The answer is `{"throttle": <float>, "steering": <float>}` with plain
numbers; steering in [-1, 1] (positive right), throttle in [0, 1] (a target speed fraction).

signlane's own simulator may add a `"time"` key (simulation seconds, same string format) so a
driver can integrate odometry in simulated time when the simulator runs in lockstep; VIA does not
send it and nothing depends on it being present.
"""
from __future__ import annotations

import base64
import binascii
import json
import math
from dataclasses import dataclass

import cv2
import numpy as np

from signlane import imagecheck

TELEMETRY_KEYS = ("steering_angle", "throttle", "speed", "image")
MAX_MESSAGE_BYTES = 8 * 1024 * 1024
MIN_IMAGE_SIDE = 16


class ProtocolError(ValueError):
    """A message that breaks the protocol: str(e) is one line saying what is wrong."""


@dataclass(frozen=True)
class Telemetry:
    """One simulator frame: image_bgr is uint8 (H, W, 3) BGR; steering_angle in degrees."""

    steering_angle: float
    throttle: float
    speed: float
    image_bgr: np.ndarray
    time: float | None = None  # simulation seconds (signlane sim only)


def _num(value: float) -> str:
    return f"{float(value):.4f}"


def encode_jpeg(image_bgr: np.ndarray, quality: int = 90) -> bytes:
    ok, buf = cv2.imencode(".jpg", image_bgr, [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:
        raise ProtocolError("cannot encode the frame as JPEG")
    return buf.tobytes()


def encode_telemetry(steering_angle: float, throttle: float, speed: float, jpeg: bytes,
                     time: float | None = None) -> str:
    """The simulator's frame message; every value a string, numbers with 4 decimals."""
    msg = {"steering_angle": _num(steering_angle), "throttle": _num(throttle), "speed": _num(speed),
           "image": base64.b64encode(jpeg).decode("ascii")}
    if time is not None:
        msg["time"] = _num(time)
    return json.dumps(msg)


def _field(msg: dict, key: str) -> float:
    if key not in msg:
        raise ProtocolError(f"telemetry has no {key!r} field")
    raw = msg[key]
    if isinstance(raw, bool) or not isinstance(raw, (str, int, float)):
        raise ProtocolError(f"telemetry field {key!r} is not a number: {str(raw)[:40]!r}")
    try:
        value = float(raw)
    except (ValueError, OverflowError):  # OverflowError: a JSON integer too big for a float
        raise ProtocolError(f"telemetry field {key!r} is not a number: {str(raw)[:40]!r}") from None
    if not math.isfinite(value):
        raise ProtocolError(f"telemetry field {key!r} is not finite: {raw!r}")
    return value


# JPEG (what VIA sends) and PNG; other bytes are refused before OpenCV sees them, as some of its
# decoders print errors to stderr for bytes they cannot read (one bad frame, one log line)
IMAGE_SIGNATURES = (b"\xff\xd8\xff", b"\x89PNG\r\n\x1a\n")


def decode_image(b64: object, max_pixels: int = imagecheck.DEFAULT_MAX_PIXELS) -> np.ndarray:
    """base64 JPEG (or PNG) -> uint8 (H, W, 3) BGR, or ProtocolError (also for more than
    `max_pixels` pixels and for corrupt data: see signlane/imagecheck.py)."""
    if not isinstance(b64, str):
        raise ProtocolError("telemetry 'image' is missing or not a string")
    if not b64:
        raise ProtocolError("telemetry 'image' is empty")
    try:
        data = base64.b64decode(b64, validate=True)
    except (binascii.Error, ValueError):
        raise ProtocolError("telemetry 'image' is not valid base64") from None
    if not data.startswith(IMAGE_SIGNATURES):
        raise ProtocolError(f"telemetry 'image' is not a JPEG ({len(data)} bytes starting {data[:8]!r})")
    try:
        img = imagecheck.decode(data, max_pixels, cv2.IMREAD_COLOR)
    except imagecheck.ImageCheckError as e:
        raise ProtocolError(f"telemetry 'image': {e}") from None
    if min(img.shape[:2]) < MIN_IMAGE_SIDE:
        raise ProtocolError(f"telemetry image is {img.shape[1]}x{img.shape[0]}, smaller than "
                            f"{MIN_IMAGE_SIDE} px on a side")
    return img


def decode_telemetry(message: str | bytes, max_bytes: int = MAX_MESSAGE_BYTES,
                     max_pixels: int = imagecheck.DEFAULT_MAX_PIXELS) -> Telemetry:
    """A frame message -> Telemetry, or ProtocolError naming the problem."""
    if isinstance(message, (bytes, bytearray)):
        raise ProtocolError(f"binary message of {len(message)} bytes (the protocol sends JSON text)")
    if len(message) > max_bytes:
        raise ProtocolError(f"message of {len(message)} bytes is over the {max_bytes}-byte limit")
    try:
        msg = json.loads(message)
    except (ValueError, RecursionError) as e:  # ValueError also covers ints over Python's digit limit
        raise ProtocolError(f"message is not JSON ({str(e)[:80]})") from None
    if not isinstance(msg, dict):
        raise ProtocolError(f"message is JSON {type(msg).__name__}, not an object")
    angle, throttle, speed = (_field(msg, k) for k in TELEMETRY_KEYS[:3])
    t = _field(msg, "time") if "time" in msg else None
    return Telemetry(angle, throttle, speed, decode_image(msg.get("image"), max_pixels), t)


def _safe(value: float, lo: float, hi: float) -> float:
    v = float(value)
    return 0.0 if not math.isfinite(v) else min(max(v, lo), hi)


def encode_command(steering: float, throttle: float) -> str:
    """The server's answer: plain numbers, clipped to the protocol's ranges; NaN becomes 0."""
    return json.dumps({"throttle": _safe(throttle, 0.0, 1.0), "steering": _safe(steering, -1.0, 1.0)})


SAFE_COMMAND = encode_command(0.0, 0.0)  # coast straight: the answer to a frame we cannot use


def decode_command(message: str | bytes) -> tuple[float, float]:
    """The simulator's side: an answer -> (steering, throttle); ProtocolError if a key is missing."""
    try:
        msg = json.loads(message)
    except (ValueError, RecursionError) as e:  # JSONDecodeError, UnicodeDecodeError, digit limit
        raise ProtocolError(f"answer is not JSON ({e})") from None
    if not isinstance(msg, dict) or "throttle" not in msg or "steering" not in msg:
        raise ProtocolError(f"answer lacks 'throttle' or 'steering': {str(message)[:80]!r}")
    try:
        steering, throttle = float(msg["steering"]), float(msg["throttle"])
    except (TypeError, ValueError, OverflowError):
        raise ProtocolError(f"answer values are not numbers: {str(message)[:80]!r}") from None
    return _safe(steering, -1.0, 1.0), _safe(throttle, 0.0, 1.0)
