"""The VIA wire protocol: exact field names, string values with 4 decimals, numeric answers."""
import base64
import json
import math

import cv2
import numpy as np
import pytest

from signlane.sim.protocol import (MAX_MESSAGE_BYTES, SAFE_COMMAND, TELEMETRY_KEYS, ProtocolError, decode_command,
                                   decode_image, decode_telemetry, encode_command, encode_jpeg, encode_telemetry)


@pytest.fixture(scope="module")
def image():
    """A 64x48 BGR gradient with a coloured block: survives JPEG well enough to compare."""
    img = np.zeros((48, 64, 3), np.uint8)
    img[..., 0] = np.linspace(0, 255, 64, dtype=np.uint8)[None, :]
    img[10:30, 20:40] = (0, 0, 255)
    return img


def b64jpeg(img, quality=95) -> str:
    return base64.b64encode(encode_jpeg(img, quality)).decode("ascii")


def test_telemetry_has_exact_keys_and_string_values(image):
    msg = json.loads(encode_telemetry(-3.14159, 0.5, 7.25, encode_jpeg(image)))
    assert tuple(msg) == TELEMETRY_KEYS == ("steering_angle", "throttle", "speed", "image")
    assert msg["steering_angle"] == "-3.1416"  # 4 decimals, rounded
    assert msg["throttle"] == "0.5000"
    assert msg["speed"] == "7.2500"
    assert all(isinstance(v, str) for v in msg.values())
    assert base64.b64decode(msg["image"])[:2] == b"\xff\xd8"  # a JPEG


def test_telemetry_round_trip(image):
    tel = decode_telemetry(encode_telemetry(12.34567, 0.25, 3.0, encode_jpeg(image, 100), time=1.5))
    assert (tel.steering_angle, tel.throttle, tel.speed, tel.time) == (12.3457, 0.25, 3.0, 1.5)
    assert tel.image_bgr.shape == (48, 64, 3) and tel.image_bgr.dtype == np.uint8
    # BGR kept: the red block is red in OpenCV order after the round trip
    b, g, r = tel.image_bgr[20, 30].astype(int)
    assert r > 200 and b < 60 and g < 60
    assert np.abs(tel.image_bgr.astype(int) - image.astype(int)).mean() < 3


def test_time_is_optional(image):
    msg = json.loads(encode_telemetry(0, 0, 0, encode_jpeg(image)))
    assert "time" not in msg
    assert decode_telemetry(json.dumps(msg)).time is None


def test_via_sample_message_decodes(image):
    """A message as the VIA simulator writes it (hand-made, not from our encoder)."""
    raw = '{"steering_angle": "-3.1416", "throttle": "0.5000", "speed": "7.2500", "image": "%s"}' % b64jpeg(image)
    tel = decode_telemetry(raw)
    assert tel.steering_angle == pytest.approx(-3.1416) and tel.speed == 7.25 and tel.throttle == 0.5


def test_command_is_plain_numbers_with_exact_keys():
    msg = json.loads(encode_command(steering=-0.25, throttle=0.4))
    assert set(msg) == {"throttle", "steering"}
    assert msg == {"throttle": 0.4, "steering": -0.25}
    assert all(type(v) is float for v in msg.values())
    assert decode_command(encode_command(0.3, 0.7)) == (0.3, 0.7)


@pytest.mark.parametrize("steering, throttle, want", [
    (2.5, 1.7, (1.0, 1.0)), (-9.0, -0.3, (-1.0, 0.0)), (math.nan, math.inf, (0.0, 0.0)),
    (-math.inf, 0.5, (0.0, 0.5)), (np.float32(0.5), np.float64(0.25), (0.5, 0.25))])
def test_command_is_clipped_and_finite(steering, throttle, want):
    text = encode_command(steering, throttle)
    assert "NaN" not in text and "Infinity" not in text  # the simulator's JSON parser rejects these
    msg = json.loads(text)
    assert (msg["steering"], msg["throttle"]) == want


def test_safe_command_coasts_straight():
    assert json.loads(SAFE_COMMAND) == {"throttle": 0.0, "steering": 0.0}


@pytest.mark.parametrize("answer", ['{"throttle": 0.5}', '{"steering": 0.1}', "[]", "not json",
                                    '{"throttle": "x", "steering": 0}', '{"throttle": null, "steering": 0}',
                                    '{"throttle": 0, "steering": %s}' % ("9" * 400)])
def test_decode_command_rejects_bad_answers(answer):
    with pytest.raises(ProtocolError):
        decode_command(answer)


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
    ("[" * 100000, "not JSON"), (b"\x00\x01", "binary")])
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


def test_size_limit(image):
    msg = _tel(image)
    with pytest.raises(ProtocolError, match="over the"):
        decode_telemetry(msg, max_bytes=len(msg) - 1)
    assert decode_telemetry(msg, max_bytes=len(msg)).speed == 1.0
    assert MAX_MESSAGE_BYTES == 8 * 1024 * 1024
