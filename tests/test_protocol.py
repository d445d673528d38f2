"""The VIA wire protocol: VIA's exact telemetry bytes (N4 strings, mph, binary frames), every number
form a VIA or another client sends, and replies read the way VIA reads them."""
import base64
import json
import math

import cv2
import numpy as np
import pytest

from signlane.sim.protocol import (MAX_MESSAGE_BYTES, MPS_PER_MPH, SAFE_COMMAND, TELEMETRY_KEYS, ProtocolError,
                                   decode_command, decode_image, decode_telemetry, encode_command, encode_jpeg,
                                   encode_telemetry, format_n4, parse_number)


@pytest.fixture(scope="module")
def image():
    """A 64x48 BGR gradient with a coloured block: survives JPEG well enough to compare."""
    img = np.zeros((48, 64, 3), np.uint8)
    img[..., 0] = np.linspace(0, 255, 64, dtype=np.uint8)[None, :]
    img[10:30, 20:40] = (0, 0, 255)
    return img


def b64jpeg(img, quality=95) -> str:
    return base64.b64encode(encode_jpeg(img, quality)).decode("ascii")


# --- telemetry bytes -------------------------------------------------------------------------
def test_message_is_vias_bytes_exactly():
    """The facts page's template, filled in by hand: no spaces, this key order, N4 strings, mph."""
    jpeg = encode_jpeg(np.full((16, 16, 3), 90, np.uint8))
    b64 = base64.b64encode(jpeg).decode("ascii")
    expected = b'{"steering_angle":"-12.5000","throttle":"0.5000","speed":"7.2500","image":"' + \
        b64.encode("ascii") + b'"}'
    assert encode_telemetry(-12.5, 0.5, 7.25 * 0.44704, jpeg) == expected
    assert "\n" not in b64 and len(b64) % 4 == 0  # standard padded base64, one line


def test_time_key_only_when_given_and_after_the_image():
    jpeg = encode_jpeg(np.full((16, 16, 3), 90, np.uint8))
    with_time = encode_telemetry(0.0, 0.0, 0.0, jpeg, time=1234.56789)
    assert with_time.endswith(b'","time":"1,234.5679"}')
    assert tuple(json.loads(with_time)) == TELEMETRY_KEYS + ("time",)
    assert b"time" not in encode_telemetry(0.0, 0.0, 0.0, jpeg)


def test_comma_locale_message():
    jpeg = encode_jpeg(np.full((16, 16, 3), 90, np.uint8))
    msg = encode_telemetry(-12.5, 0.5, 1234.5 * MPS_PER_MPH, jpeg, decimal=",")
    assert msg.startswith(b'{"steering_angle":"-12,5000","throttle":"0,5000","speed":"1.234,5000","image":"')
    tel = decode_telemetry(msg)
    assert (tel.wheel_deg, tel.pedal) == (-12.5, 0.5)
    assert tel.speed_mps == pytest.approx(1234.5 * MPS_PER_MPH, abs=1e-9)


def test_vias_message_decodes_to_si_units(image):
    """A message as VIA writes it (by hand, not from our encoder): degrees, pedal, mph."""
    jpeg = encode_jpeg(image)
    raw = ('{"steering_angle":"\u22123.1416","throttle":"0.5000","speed":"10.0000","image":"%s"}'
           % base64.b64encode(jpeg).decode()).encode("utf-8")
    tel = decode_telemetry(raw)
    assert tel.wheel_deg == -3.1416 and tel.pedal == 0.5 and tel.time is None
    assert tel.speed_mps == pytest.approx(4.4704, abs=1e-12)  # 10 mph
    assert tel.jpeg == jpeg  # the bytes as received, for a recorder


def test_round_trip_keeps_image_and_numbers(image):
    tel = decode_telemetry(encode_telemetry(12.34567, 0.5, 3.0, encode_jpeg(image, 100), time=1.5))
    assert (tel.wheel_deg, tel.pedal, tel.time) == (12.3457, 0.5, 1.5)
    assert tel.speed_mps == pytest.approx(3.0, abs=0.5e-4 * MPS_PER_MPH)  # 4 decimals of mph
    assert tel.image_bgr.shape == (48, 64, 3) and tel.image_bgr.dtype == np.uint8
    b, g, r = tel.image_bgr[20, 30].astype(int)  # BGR kept: the red block is red in OpenCV order
    assert r > 200 and b < 60 and g < 60
    assert np.abs(tel.image_bgr.astype(int) - image.astype(int)).mean() < 3


def test_binary_and_text_frames_decode_the_same(image):
    msg = encode_telemetry(-7.0, 0.5, 6.0, encode_jpeg(image), time=2.0)
    a, b, c = decode_telemetry(msg), decode_telemetry(msg.decode("utf-8")), decode_telemetry(bytearray(msg))
    assert (a.wheel_deg, a.pedal, a.speed_mps, a.time, a.jpeg) == (b.wheel_deg, b.pedal, b.speed_mps, b.time, b.jpeg)
    assert np.array_equal(a.image_bgr, b.image_bgr) and np.array_equal(a.image_bgr, c.image_bgr)


def test_invalid_utf8_is_one_line():
    msg = b'{"steering_angle":"0.0000","throttle":"\xff\xfe"}'
    with pytest.raises(ProtocolError, match="not UTF-8") as e:
        decode_telemetry(msg)
    assert "\n" not in str(e.value) and f"byte 0xff at {msg.index(0xff)}" in str(e.value)


def _jpeg_segments(jpeg: bytes, marker: bytes) -> list[bytes]:
    """The payloads of every header segment with this marker (before the scan data)."""
    out, i = [], 2
    while jpeg[i + 1] != 0xDA:  # start of scan: the headers end
        n = int.from_bytes(jpeg[i + 2:i + 4], "big")
        if jpeg[i:i + 2] == marker:
            out.append(jpeg[i + 4:i + 2 + n])
        i += 2 + n
    return out


def test_jpeg_is_quality_75_and_420(image):
    jpeg = encode_jpeg(image)
    [sof] = _jpeg_segments(jpeg, b"\xff\xc0")  # baseline frame header
    comps = [(sof[6 + 3 * k], sof[7 + 3 * k]) for k in range(sof[5])]
    assert [(cid, hv) for cid, hv in comps] == [(1, 0x22), (2, 0x11), (3, 0x11)]  # Y 2x2, Cb and Cr 1x1: 4:2:0
    dqt = b"".join(_jpeg_segments(jpeg, b"\xff\xdb"))
    # libjpeg scales its base tables (first entries 16 and 17) by 200 - 2 * 75 = 50 %: 8 and 9
    tables = {dqt[k]: dqt[k + 1] for k in range(0, len(dqt), 65)}
    assert tables == {0: 8, 1: 9}


# --- numbers ---------------------------------------------------------------------------------
@pytest.mark.parametrize("value, decimal, text", [
    (1234.5, ".", "1,234.5000"), (1234.5, ",", "1.234,5000"), (-1234567.25, ".", "-1,234,567.2500"),
    (-1234567.25, ",", "-1.234.567,2500"), (0.5, ",", "0,5000"), (-12.5, ".", "-12.5000"), (0.0, ".", "0.0000"),
    (-0.00001, ".", "0.0000"),  # Mono writes no minus on a value that rounds to zero
    (0.03125, ".", "0.0313"),  # an exact tie: .NET rounds half away from zero
    (-0.03125, ".", "-0.0313"), (999.99995, ".", "1,000.0000"), (25.0, ".", "25.0000")])
def test_format_n4(value, decimal, text):
    assert format_n4(value, decimal) == text


@pytest.mark.parametrize("value, decimal", [(math.nan, "."), (math.inf, "."), (1.0, ";"), (1.0, "")])
def test_format_n4_refuses(value, decimal):
    with pytest.raises(ValueError):
        format_n4(value, decimal)


@pytest.mark.parametrize("raw, value", [
    (7.25, 7.25), (-3, -3.0), (0, 0.0),  # JSON numbers
    ("7.2500", 7.25), ("1,234.5000", 1234.5), ("-1,234,567.2500", -1234567.25),  # N4, '.' decimal
    ("0,5000", 0.5), ("-12,5000", -12.5), ("1.234,5000", 1234.5), ("1 234,5000", 1234.5),  # N4, ',' decimal
    ("1\u00a0234,5000", 1234.5), ("1\u202f234,5000", 1234.5), ("1'234,5000", 1234.5),
    ("1\u202f234\u202f567,2500", 1234567.25), ("1'234.5000", 1234.5),  # de-CH: apostrophe with '.'
    ("\u22123.1416", -3.1416), ("\u22121\u00a0234,5000", -1234.5),  # U+2212 minus
    ("0.5", 0.5), ("7.25", 7.25), ("-3", -3.0), ("12", 12.0), ("1e-05", 1e-05),  # plain, other clients
    ("1,2345", 1.2345),  # a separator before exactly 4 final digits is N4's decimal mark
    ("1.234", 1.234),  # not N4 (3 decimals): the plain form, '.' decimal
])
def test_numbers_accepted(raw, value):
    assert parse_number("speed", raw) == value


@pytest.mark.parametrize("raw, why", [
    ("", "not a number"), ("fast", "not a number"), ("nan", "not finite"), ("NaN", "not finite"),
    ("Infinity", "not finite"), ("-inf", "not finite"), ("\u221e", "not finite"), ("9" * 400, "not finite"),
    (math.nan, "not finite"), (math.inf, "not finite"), (True, "not a number"), (False, "not a number"),
    ([1], "not a number"), ({"v": 1}, "not a number"), (None, "not a number"), (10 ** 400, "not a number"),
    ("1,234", "not a number"),  # N4 always has 4 decimals; plain numbers have no groups
    ("0,5", "not a number"), ("12,34.5000", "not a number"), ("1,23,456.0000", "not a number"),
    ("1.234.5000", "not a number"), ("1,234,5000", "not a number"),  # a group mark equal to the decimal mark
    ("1,234 567.0000", "not a number"),  # two kinds of group mark
    ("1,234.50000", "not a number"), (",1234", "not a number"), (" 1.0", "not a number"), ("1_000", "not a number"),
    ("\u0663", "not a number"), ("--1", "not a number"), ("+1", "not a number"), ("1;2345", "not a number"),
    ("x" * 500, "not a number")])
def test_numbers_refused_in_one_line_naming_key_and_value(raw, why):
    with pytest.raises(ProtocolError, match=why) as e:
        parse_number("throttle", raw)
    text = str(e.value)
    assert "'throttle'" in text and "\n" not in text and len(text) < 120  # the value is truncated
    assert str(raw)[:10] in text or repr(str(raw)[:10])[1:-1] in text


@pytest.mark.parametrize("decimal", [".", ","])
@pytest.mark.parametrize("value", [0.0, 0.5, -12.5, 25.0, 13.4112, 1234.5, -98765.4321, 1234567.125, 1e-4])
def test_n4_round_trips(value, decimal):
    assert parse_number("speed", format_n4(value, decimal)) == round(value, 4)


# --- replies ---------------------------------------------------------------------------------
def test_command_is_plain_numbers_with_exact_keys():
    msg = json.loads(encode_command(steering=-0.25, throttle=0.4))
    assert list(msg) == ["throttle", "steering"] and msg == {"throttle": 0.4, "steering": -0.25}
    assert all(type(v) is float for v in msg.values())
    assert decode_command(encode_command(0.3, 0.7)) == (0.3, 0.7)


@pytest.mark.parametrize("steering, throttle, want", [
    (2.5, 1.7, (1.0, 1.0)), (-9.0, -0.3, (-1.0, 0.0)), (math.nan, math.inf, (0.0, 0.0)),
    (-math.inf, 0.5, (0.0, 0.5)), (np.float32(0.5), np.float64(0.25), (0.5, 0.25))])
def test_command_is_clipped_and_finite(steering, throttle, want):
    text = encode_command(steering, throttle)
    assert "NaN" not in text and "Infinity" not in text  # the simulator's float parser would take NaN
    msg = json.loads(text)
    assert (msg["steering"], msg["throttle"]) == want


def test_safe_command_coasts_straight():
    assert json.loads(SAFE_COMMAND) == {"throttle": 0.0, "steering": 0.0}


@pytest.mark.parametrize("reply, want", [
    ('{"throttle": 0.5, "steering": -0.12}', (-0.12, 0.5)),  # the tutorial's server
    (b'{"throttle": 0.5, "steering": -0.12}', (-0.12, 0.5)),  # a binary reply
    ('{"steering":1,"throttle":0}', (1.0, 0.0)),
    ('{"throttle": 0.3, "steering": 0.2, "brake": 1, "note": "hi"}', (0.2, 0.3)),  # extra flat keys
    ('{"throttle": "0.3", "steering": "-2.5"}', (-2.5, 0.3)),  # quotes deleted; the car clamps steering
    ('throttle:0.25,steering:1e-3', (0.001, 0.25)),  # braces and quotes are not required either
    ('{"throttle": 1.7, "steering": 0}', (0.0, 1.7))])
def test_replies_read_as_via_reads_them(reply, want):
    assert decode_command(reply) == want


@pytest.mark.parametrize("reply, match", [
    ('{"throttle": {"v": 0.5}, "steering": 0}', "not flat"),  # nested value
    ('{"throttle": [0.5, 1], "steering": 0}', "not flat"), ('{"throttle": 0.5}', "no 'steering'"),
    ('{"steering": 0.1}', "no 'throttle'"), ("{}", "not flat"), ("", "not flat"), ("not json", "not flat"),
    ('{"throttle": "x", "steering": 0}', "not a number"), ('{"throttle": null, "steering": 0}', "not a number"),
    ('{"throttle": NaN, "steering": 0}', "not a number"),
    ('{"throttle": 0, "steering": %s}' % ("9" * 400), "not finite"),
    ('{"throttle": 0.5, "steering": -0.12,}', "not flat"), (b"\xff\x00", "not UTF-8")])
def test_replies_via_would_ignore_are_refused(reply, match):
    with pytest.raises(ProtocolError, match=match) as e:
        decode_command(reply)
    assert "\n" not in str(e.value)


# --- bad frames ------------------------------------------------------------------------------
def _tel(img, **over) -> str:
    msg = {"steering_angle": "0.0000", "throttle": "0.0000", "speed": "1.0000", "image": b64jpeg(img)}
    msg.update(over)
    return json.dumps({k: v for k, v in msg.items() if v is not None})


@pytest.mark.parametrize("key", TELEMETRY_KEYS)
def test_missing_key_is_named(image, key):
    with pytest.raises(ProtocolError, match=key):
        decode_telemetry(_tel(image, **{key: None}))


@pytest.mark.parametrize("field, value, match", [
    ("speed", "fast", "not a number"), ("speed", "nan", "not finite"), ("throttle", "inf", "not finite"),
    ("steering_angle", [1], "not a number"), ("speed", True, "not a number"), ("speed", 10 ** 400, "not a number"),
    ("time", "1,234", "'time' is not a number"),
    ("image", "@@not base64@@", "base64"), ("image", base64.b64encode(b"hello world").decode(), "not a JPEG"),
    ("image", base64.b64encode(b"\xff\xd8\xff" + b"\x00" * 50).decode(), "decodable"),
    ("image", "", "empty"), ("image", 7, "not a string")])
def test_bad_fields_give_one_line_errors(image, field, value, match):
    with pytest.raises(ProtocolError, match=match) as e:
        decode_telemetry(_tel(image, **{field: value}))
    assert "\n" not in str(e.value)


@pytest.mark.parametrize("message, match", [
    ("{not json", "not JSON"), ("[1, 2]", "not an object"), ('"text"', "not an object"),
    ('{"speed": %s}' % ("1" * 5000), "not JSON"),  # over Python's int digit limit: a ValueError, not a crash
    ("[" * 100000, "not JSON"), (b"\x00\x01", "not JSON"), (b"[" * 100000, "not JSON"),
    (b"\xef\xbb\xbf{}", "not JSON"), (12, "not text or bytes")])
def test_bad_messages(message, match):
    with pytest.raises(ProtocolError, match=match):
        decode_telemetry(message)


def test_nan_literal_is_not_finite(image):
    raw = _tel(image).replace('"1.0000"', "NaN")  # Python's json accepts the bare literal
    with pytest.raises(ProtocolError, match="not finite"):
        decode_telemetry(raw)


@pytest.mark.parametrize("side", [1, 8])
def test_tiny_images_are_refused(side):
    tiny = np.full((side, side, 3), 128, np.uint8)
    with pytest.raises(ProtocolError, match=f"{side}x{side}"):
        decode_image(b64jpeg(tiny))


def test_png_is_accepted_too():
    img = np.full((20, 30, 3), 77, np.uint8)
    ok, buf = cv2.imencode(".png", img)
    assert decode_image(base64.b64encode(buf.tobytes()).decode()).shape == (20, 30, 3)


@pytest.mark.parametrize("kind", [str, bytes])
def test_size_limit_applies_to_both_kinds(image, kind):
    msg = _tel(image) if kind is str else _tel(image).encode()
    with pytest.raises(ProtocolError, match="over the"):
        decode_telemetry(msg, max_bytes=len(msg) - 1)
    assert decode_telemetry(msg, max_bytes=len(msg)).speed_mps == MPS_PER_MPH
    assert MAX_MESSAGE_BYTES == 8 * 1024 * 1024


def test_mangled_messages_raise_only_protocol_errors():
    """Seeded byte mutations of a valid message: decoding either works or says ProtocolError."""
    good = encode_telemetry(-12.5, 0.5, 7.0, encode_jpeg(np.full((16, 16, 3), 90, np.uint8)), time=3.0)
    rng = np.random.default_rng(0)
    ok = refused = 0
    for _ in range(400):
        msg = bytearray(good)
        for _ in range(int(rng.integers(1, 4))):
            i = int(rng.integers(len(msg)))
            op = rng.integers(3)
            if op == 0:
                msg[i] = int(rng.integers(256))
            elif op == 1:
                del msg[i]
            else:
                msg[i:i] = bytes([int(rng.integers(256))])
        try:
            decode_telemetry(bytes(msg))
            ok += 1
        except ProtocolError:
            refused += 1
    assert ok + refused == 400 and refused > 100
