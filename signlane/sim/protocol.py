"""The VIA simulator's WebSocket protocol: telemetry (simulator -> server) and replies (server -> simulator).

Telemetry is one **binary** frame per rendered image holding UTF-8 JSON with no spaces, in this key
order, every value a string (VIA.md section 1):
  `{"steering_angle":"-12.5000","throttle":"0.5000","speed":"7.2500","image":"<base64 JPEG>"}`
Numbers are .NET `N4`: 4 decimals, thousands separators, the decimal mark of the sending machine's
locale (`"0,5000"` on a comma-decimal machine). `steering_angle` is the applied wheel angle in
degrees (+ right), `throttle` the pedal actually applied (VIA sends only 0 or 0.5: not the
command), `speed` miles per hour. Units are converted here, once: `Telemetry` holds m/s.

The reply is text JSON with plain numbers, `{"throttle": <float>, "steering": <float>}`; steering
in [-1, 1] (positive right), throttle a target fraction of VIA's 30 mph top speed.

signlane's own simulator adds a `"time"` key (simulated seconds, after `image`) only when it runs
in lockstep over a socket, so a server can keep simulated time; VIA never sends it.
"""
from __future__ import annotations

import base64
import binascii
import json
import math
import re
from dataclasses import dataclass
from decimal import ROUND_HALF_UP, Decimal

import cv2
import numpy as np

from signlane import imagecheck

TELEMETRY_KEYS = ("steering_angle", "throttle", "speed", "image")
MAX_MESSAGE_BYTES = 8 * 1024 * 1024
MIN_IMAGE_SIDE = 16
MPS_PER_MPH = 0.44704  # exact: 1 mile = 1609.344 m


class ProtocolError(ValueError):
    """A message that breaks the protocol: str(e) is one line saying what is wrong."""


@dataclass(frozen=True)
class Telemetry:
    """One simulator frame, in SI units. image_bgr is uint8 (H, W, 3) BGR."""

    wheel_deg: float  # applied wheel angle, degrees, + right (VIA's steering_angle)
    pedal: float  # the pedal actually applied, 0..1 (VIA: 0 or 0.5); not the command
    speed_mps: float
    image_bgr: np.ndarray
    time: float | None = None  # simulated seconds (signlane sim in lockstep only)
    jpeg: bytes | None = None  # the image bytes exactly as received, for recorders


# --- numbers ---------------------------------------------------------------------------------
# .NET formats N4 with the locale's group separator: ',' or '.' in most locales; a space,
# U+00A0 or U+202F in French, Scandinavian and Slavic ones; an apostrophe (ASCII or U+2019) in
# Swiss ones (de-CH pairs it with a '.' decimal mark).
_GROUPS = {".": ",' \u00a0\u202f\u2019", ",": ".' \u00a0\u202f\u2019"}
_MINUS = "\u2212"  # ICU locales (sv, fi, ...) write a real minus sign
_PLAIN = re.compile(r"-?[0-9]+(?:\.[0-9]+)?(?:[eE][+-]?[0-9]+)?")  # other clients' str(float), exponents too
_DIGITS = re.compile(r"[0-9]+")  # ASCII only: Python's float() would also take other scripts' digits
_NON_FINITE = {"nan", "-nan", "inf", "-inf", "+inf", "infinity", "-infinity", "\u221e", "-\u221e"}


def parse_number(key: str, raw: object) -> float:
    """A telemetry value -> float, or ProtocolError naming the key and the value.

    Accepted: JSON numbers; N4 strings with either decimal mark and any of the locales' group
    separators (`"1,234.5000"`, `"0,5000"`, `"1.234,5000"`, `"1 234,5000"`); a U+2212 minus as well
    as '-'; plain decimal strings (`"0.5"`, `"-3"`, `"1e-05"`). An ambiguous string is read the
    N4 way: N4 always has exactly 4 decimals, so a '.' or ',' followed by exactly 4 final digits
    is the decimal mark (`"1,2345"` is 1.2345) and every other separator must group the integer
    part in threes with one character that is not the decimal mark. Otherwise only the plain form
    applies, whose decimal mark is '.' (`"1.234"` is 1.234; `"1,234"` and `"0,5"` are refused).
    """
    if isinstance(raw, bool) or not isinstance(raw, (str, int, float)):
        raise ProtocolError(f"telemetry field {key!r} is not a number: {_show(raw)}")
    if isinstance(raw, str):
        value = _parse_string(key, raw)
    else:
        try:
            value = float(raw)
        except OverflowError:  # a JSON integer too big for a float
            raise ProtocolError(f"telemetry field {key!r} is not a number: {_show(raw)}") from None
    if not math.isfinite(value):
        raise ProtocolError(f"telemetry field {key!r} is not finite: {_show(raw)}")
    return value


def _parse_string(key: str, raw: str) -> float:
    text = "-" + raw[1:] if raw.startswith(_MINUS) else raw
    if _PLAIN.fullmatch(text):
        return float(text)  # 400 digits give inf: refused as not finite by the caller
    value = _parse_n4(text)
    if value is not None:
        return value
    if text.strip().lower() in _NON_FINITE:
        raise ProtocolError(f"telemetry field {key!r} is not finite: {_show(raw)}")
    raise ProtocolError(f"telemetry field {key!r} is not a number: {_show(raw)}")


def _parse_n4(text: str) -> float | None:
    """N4 with any locale's marks, or None: `[-]int<mark>dddd`, the integer part plain or grouped
    in threes by one separator that is not the decimal mark."""
    sign, body = ("-", text[1:]) if text.startswith("-") else ("", text)
    whole, mark, decimals = body[:-5], body[-5:-4], body[-4:]
    if mark not in _GROUPS or not _DIGITS.fullmatch(decimals) or not whole:
        return None
    if not _DIGITS.fullmatch(whole):
        group = next(c for c in whole if c not in "0123456789")
        parts = whole.split(group)
        if group not in _GROUPS[mark] or not 1 <= len(parts[0]) <= 3 or \
                not all(len(p) == 3 for p in parts[1:]) or not all(_DIGITS.fullmatch(p) for p in parts):
            return None
        whole = "".join(parts)
    return float(f"{sign}{whole}.{decimals}")


def _show(raw: object) -> str:
    s = str(raw)
    return repr(s if len(s) <= 40 else s[:40] + "...")


def format_n4(value: float, decimal: str = ".") -> str:
    """A number as .NET's `ToString("N4")` writes it: 4 decimals, thousands grouped
    (`1234.5` -> `"1,234.5000"`; with decimal="," -> `"1.234,5000"`).

    As Mono's (Unity 2019's .NET) formatter: the double is first taken to 15 significant digits,
    then rounded half away from zero, and a value that rounds to zero has no minus sign."""
    if decimal not in _GROUPS:
        raise ValueError(f"decimal mark must be '.' or ',', not {decimal!r}")
    v = float(value)
    if not math.isfinite(v):
        raise ValueError(f"cannot send a non-finite number ({v})")
    d = Decimal(f"{v:.14e}").quantize(Decimal("0.0001"), rounding=ROUND_HALF_UP)
    text = f"{abs(d) if d.is_zero() else d:,.4f}"
    return text if decimal == "." else text.translate(str.maketrans(",.", ".,"))


# --- telemetry -------------------------------------------------------------------------------
def encode_jpeg(image_bgr: np.ndarray, quality: int = 75) -> bytes:
    """uint8 (H, W, 3) BGR -> JPEG bytes as VIA makes them: quality 75, 4:2:0 chroma subsampling."""
    params = [cv2.IMWRITE_JPEG_QUALITY, int(quality),
              cv2.IMWRITE_JPEG_SAMPLING_FACTOR, cv2.IMWRITE_JPEG_SAMPLING_FACTOR_420]
    ok, buf = cv2.imencode(".jpg", image_bgr, params)
    if not ok:
        raise ProtocolError("cannot encode the frame as JPEG")
    return buf.tobytes()


def encode_telemetry(wheel_deg: float, pedal: float, speed_mps: float, jpeg: bytes, time: float | None = None,
                     decimal: str = ".") -> bytes:
    """The simulator's frame message, byte for byte as VIA builds it (speed sent in mph); the
    `"time"` key (signlane's lockstep extension) only when `time` is given."""
    msg = {"steering_angle": format_n4(wheel_deg, decimal), "throttle": format_n4(pedal, decimal),
           "speed": format_n4(speed_mps / MPS_PER_MPH, decimal), "image": base64.b64encode(jpeg).decode("ascii")}
    if time is not None:
        msg["time"] = format_n4(time, decimal)
    return json.dumps(msg, separators=(",", ":")).encode("utf-8")


# JPEG (what VIA sends) and PNG; other bytes are refused before OpenCV sees them, as some of its
# decoders print errors to stderr for bytes they cannot read (one bad frame, one log line)
IMAGE_SIGNATURES = (b"\xff\xd8\xff", b"\x89PNG\r\n\x1a\n")


def _image_bytes(b64: object) -> bytes:
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
    return data


def _image_from_bytes(data: bytes, max_pixels: int = imagecheck.DEFAULT_MAX_PIXELS) -> np.ndarray:
    try:
        img = imagecheck.decode(data, max_pixels, cv2.IMREAD_COLOR)
    except imagecheck.ImageCheckError as e:
        raise ProtocolError(f"telemetry 'image': {e}") from None
    if min(img.shape[:2]) < MIN_IMAGE_SIDE:
        raise ProtocolError(f"telemetry image is {img.shape[1]}x{img.shape[0]}, smaller than "
                            f"{MIN_IMAGE_SIDE} px on a side")
    return img


def decode_image(b64: object, max_pixels: int = imagecheck.DEFAULT_MAX_PIXELS) -> np.ndarray:
    """base64 JPEG (or PNG) -> uint8 (H, W, 3) BGR, or ProtocolError (also for more than
    `max_pixels` pixels and for corrupt data: see signlane/imagecheck.py)."""
    return _image_from_bytes(_image_bytes(b64), max_pixels)


def _text(message: object, what: str) -> str:
    if isinstance(message, (bytes, bytearray, memoryview)):
        try:
            return bytes(message).decode("utf-8")
        except UnicodeDecodeError as e:
            raise ProtocolError(f"binary {what} of {len(message)} bytes is not UTF-8 "
                                f"(byte {e.object[e.start]:#04x} at {e.start})") from None
    if not isinstance(message, str):
        raise ProtocolError(f"{what} is a {type(message).__name__}, not text or bytes")
    return message


def decode_telemetry(message: str | bytes, max_bytes: int = MAX_MESSAGE_BYTES,
                     max_pixels: int = imagecheck.DEFAULT_MAX_PIXELS) -> Telemetry:
    """A frame message (binary UTF-8, as VIA sends, or text) -> Telemetry in SI units, or
    ProtocolError naming the problem; it raises nothing else. The size limit counts bytes of a
    binary frame and characters of a text one."""
    if isinstance(message, (str, bytes, bytearray, memoryview)) and len(message) > max_bytes:
        raise ProtocolError(f"message of {len(message)} bytes is over the {max_bytes}-byte limit")
    text = _text(message, "message")
    try:
        msg = json.loads(text)
    except (ValueError, RecursionError) as e:  # ValueError also covers ints over Python's digit limit
        raise ProtocolError(f"message is not JSON ({str(e)[:80]})") from None
    if not isinstance(msg, dict):
        raise ProtocolError(f"message is JSON {type(msg).__name__}, not an object")
    for key in TELEMETRY_KEYS:
        if key not in msg:
            raise ProtocolError(f"telemetry has no {key!r} field")
    angle, pedal, mph = (parse_number(k, msg[k]) for k in TELEMETRY_KEYS[:3])
    t = parse_number("time", msg["time"]) if "time" in msg else None
    data = _image_bytes(msg["image"])
    return Telemetry(angle, pedal, mph * MPS_PER_MPH, _image_from_bytes(data, max_pixels), t, data)


# --- replies ---------------------------------------------------------------------------------
def _safe(value: float, lo: float, hi: float) -> float:
    v = float(value)
    return 0.0 if not math.isfinite(v) else min(max(v, lo), hi)


def encode_command(steering: float, throttle: float) -> str:
    """The server's answer: plain numbers, clipped to the protocol's ranges; NaN becomes 0."""
    return json.dumps({"throttle": _safe(throttle, 0.0, 1.0), "steering": _safe(steering, -1.0, 1.0)})


SAFE_COMMAND = encode_command(0.0, 0.0)  # coast straight: the answer to a frame we cannot use

_REPLY_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")


def decode_command(message: str | bytes) -> tuple[float, float]:
    """The simulator's side: a reply (text or binary) -> (steering, throttle), read as VIA reads it.

    VIA deletes every '{', '}' and '"', splits on ',' and then ':', and parses `throttle` and
    `steering` as floats: both are required, other flat keys are ignored, and a nested value (or
    a list) leaves a piece that is not one `key:value` pair. Values are returned unclipped (the
    car clamps steering; throttle only ever meets a speed fraction); a non-finite number is
    refused, so it can never reach the car. ProtocolError means "ignore this reply"."""
    text = _text(message, "reply")
    for ch in '{}"':
        text = text.replace(ch, "")
    values: dict[str, str] = {}
    for piece in text.split(","):
        parts = piece.split(":")
        if len(parts) != 2:
            raise ProtocolError(f"reply is not flat key:value pairs (at {piece.strip()[:40]!r})")
        values[parts[0].strip()] = parts[1].strip()
    out = []
    for key in ("steering", "throttle"):
        if key not in values:
            raise ProtocolError(f"reply has no {key!r}: {text[:80]!r}")
        if not _REPLY_NUMBER.fullmatch(values[key]):
            raise ProtocolError(f"reply {key!r} is not a number: {values[key][:40]!r}")
        v = float(values[key])
        if not math.isfinite(v):
            raise ProtocolError(f"reply {key!r} is not finite: {values[key][:40]!r}")
        out.append(v)
    return out[0], out[1]
