"""Image bytes checked before decoding (signlane/imagecheck.py): sizes from headers, the pixel
limit, corrupt JPEG and PNG data found without libjpeg's stderr, no false alarms on valid files;
and the telemetry parser under property-based fuzzing (only ProtocolError ever comes out)."""
import base64
import json
import re
import struct
import subprocess
import sys
import zlib

import cv2
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from signlane import imagecheck as ic
from signlane.sim.protocol import TELEMETRY_KEYS, ProtocolError, decode_image, decode_telemetry, encode_telemetry
from signlane.world.sampling import FrameSampler, SamplerConfig

LIBJPEG_WARNS = ("Corrupt JPEG data", "Premature end of JPEG file", "Invalid JPEG file structure")


@pytest.fixture(scope="module")
def road():
    smp = FrameSampler(11, SamplerConfig(320, 240, effects="clean", randomise=False, lateral_m=0.1, heading_deg=1))
    return smp.sample(0).image


def jpeg(image, quality=90, **flags) -> bytes:
    params = [cv2.IMWRITE_JPEG_QUALITY, quality]
    for name, value in flags.items():
        params += [getattr(cv2, f"IMWRITE_JPEG_{name.upper()}"), value]
    ok, buf = cv2.imencode(".jpg", image, params)
    assert ok
    return buf.tobytes()


def corrupt(data: bytes, seed: int, n: int = 40, at: float = 0.5) -> bytes:
    """`n` random bytes written over the data at fraction `at` of the file (mid-scan)."""
    d = bytearray(data)
    i = int(len(d) * at)
    d[i:i + n] = np.random.default_rng(seed).integers(0, 256, n, dtype=np.uint8).tobytes()
    return bytes(d)


def libjpeg_warnings(files: list[bytes]) -> list[str]:
    """What OpenCV's libjpeg prints on stderr for each file, decoded in a child process."""
    code = ("import os, sys, cv2, numpy as np\n"
            "n = int.from_bytes(sys.stdin.buffer.read(4), 'big')\n"
            "for _ in range(n):\n"
            "    k = int.from_bytes(sys.stdin.buffer.read(4), 'big')\n"
            "    cv2.imdecode(np.frombuffer(sys.stdin.buffer.read(k), np.uint8), cv2.IMREAD_COLOR)\n"
            "    os.write(2, b'@@\\n')\n")
    payload = len(files).to_bytes(4, "big") + b"".join(len(f).to_bytes(4, "big") + f for f in files)
    err = subprocess.run([sys.executable, "-c", code], input=payload, capture_output=True, check=True).stderr
    return err.decode(errors="replace").split("@@\n")[:-1]


def with_size(data: bytes, width: int, height: int) -> bytes:
    """A JPEG (SOF) or PNG (IHDR, CRC fixed) whose header claims another size."""
    d = bytearray(data)
    if data[:2] == b"\xff\xd8":
        i = 2
        while d[i + 1] not in ic.SOF_MARKERS:
            i += 2 + int.from_bytes(d[i + 2:i + 4], "big")
        d[i + 5:i + 9] = struct.pack(">HH", height, width)
    else:
        d[16:24] = struct.pack(">II", width, height)
        d[29:33] = struct.pack(">I", zlib.crc32(bytes(d[12:29])))
    return bytes(d)


# ------------------------------------------------------------------------------ sizes and limits
def test_sizes_come_from_headers_without_decoding(road):
    small = road[:120, :200]
    for ext in (".jpg", ".png", ".bmp", ".tiff", ".webp"):
        ok, buf = cv2.imencode(ext, small)
        assert ok and ic.header_size(buf.tobytes()) == (200, 120), ext
    assert ic.header_size(with_size(jpeg(small), 12000, 12000)) == (12000, 12000)
    assert ic.header_size(with_size(cv2.imencode(".png", small)[1].tobytes(), 20000, 20000)) == (20000, 20000)
    with pytest.raises(ic.ImageCheckError, match="not an image"):
        ic.header_size(b"GIF89a" + b"\0" * 20)


def test_pixel_limit_refuses_before_decoding(road, monkeypatch):
    huge = with_size(jpeg(road), 12000, 12000)  # 3 bytes of header make a 432 MB image
    monkeypatch.setattr(ic.cv2, "imdecode", lambda *a: pytest.fail("decoded an image over the limit"))
    with pytest.raises(ic.ImageCheckError, match=r"12000x12000 px, over the limit of 16777216 pixels \(4096x4096\)"):
        ic.decode(huge)
    with pytest.raises(ic.ImageCheckError, match="320x240 px, over the limit of 10000 pixels"):
        ic.decode(jpeg(road), max_pixels=100 * 100)


def test_telemetry_with_a_huge_image_is_a_protocol_error(road):
    message = encode_telemetry(0.0, 0.3, 5.0, with_size(jpeg(road), 12000, 12000))
    with pytest.raises(ProtocolError, match="12000x12000 px, over the limit"):
        decode_telemetry(message)
    assert decode_telemetry(encode_telemetry(0.0, 0.3, 5.0, jpeg(road))).image_bgr.shape == (240, 320, 3)


# ------------------------------------------------------------------------------ corrupt data
def test_corrupt_jpeg_mid_scan_is_refused_where_libjpeg_only_warns(road):
    good = jpeg(road)
    bad = [corrupt(good, seed=k) for k in range(4, 12)]  # 40 bytes mid-scan, eight ways
    warned = libjpeg_warnings([good] + bad)
    assert warned[0] == ""
    hits = [(b, w) for b, w in zip(bad, warned[1:]) if "Corrupt JPEG data" in w]
    assert len(hits) >= 2  # random bytes mid-scan usually break it
    counted = 0
    for data, warning in hits:
        img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)  # OpenCV decodes it anyway
        assert img is not None and np.abs(img.astype(int) - road).mean() > 5  # a smeared picture
        with pytest.raises(ProtocolError, match=r"^telemetry 'image': corrupt JPEG data \(") as e:
            decode_telemetry(encode_telemetry(0.0, 0.3, 5.0, data))
        # where both count the bytes left over after the last block, they agree but for the
        # few bytes libjpeg has already read into its bit buffer
        theirs = re.search(r"(\d+) extraneous bytes before marker", warning)
        ours = re.search(r"\((\d+) extraneous bytes in the scan at byte \d+\)", str(e.value))
        if theirs and ours:
            assert 0 <= int(ours[1]) - int(theirs[1]) <= 8, (warning, str(e.value))
            counted += 1
    assert counted >= 1


def test_every_jpeg_libjpeg_warns_about_is_refused(road):
    """Seeded corruptions of 1-40 bytes anywhere in the scan, with and without restart markers:
    every file libjpeg warns about fails the check (it also catches some libjpeg lets pass)."""
    files = []
    for k in range(48):
        base = jpeg(road, (50, 75, 90, 95)[k % 4], rst_interval=(0, 0, 2)[k % 3])
        files.append(corrupt(base, seed=100 + k, n=(1, 5, 40)[k % 3], at=0.1 + 0.8 * ((k * 7) % 48) / 48))
    warned = [any(w in text for w in LIBJPEG_WARNS) for text in libjpeg_warnings(files)]
    flagged = []
    for f in files:
        try:
            ic.check_jpeg(f)
            flagged.append(False)
        except ic.ImageCheckError:
            flagged.append(True)
    assert sum(warned) >= 15  # the set holds many damaged files
    assert [k for k in range(len(files)) if warned[k] and not flagged[k]] == []


@pytest.mark.parametrize("shape", [(240, 320), (177, 333), (19, 17), (1, 1), (9, 700)])
def test_valid_jpegs_pass(road, shape):
    """No false alarm: every quality, restart intervals, optimised tables, progressive,
    greyscale and chroma subsampling, odd sizes."""
    img = cv2.resize(road, shape[::-1], interpolation=cv2.INTER_AREA)
    noise = np.random.default_rng(0).integers(0, 256, img.shape, dtype=np.uint8)  # long codes, 0xFF bytes
    count = 0
    for src in (img, noise, cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)):
        for q in (1, 10, 35, 60, 85, 95, 100):
            for flags in ({}, {"rst_interval": 1}, {"rst_interval": 5, "optimize": 1}, {"progressive": 1},
                          {"sampling_factor": cv2.IMWRITE_JPEG_SAMPLING_FACTOR_444},
                          {"sampling_factor": cv2.IMWRITE_JPEG_SAMPLING_FACTOR_422, "rst_interval": 3}):
                if src.ndim == 2 and "sampling_factor" in flags:
                    continue
                data = jpeg(src, q, **flags)
                ic.check_jpeg(data)
                assert ic.header_size(data) == (shape[1], shape[0])
                count += 1
    assert count == 7 * (6 + 6 + 4)


def test_restart_markers_out_of_sequence_and_truncation_are_found(road):
    data = jpeg(road, rst_interval=4)
    rst = [i for i in range(len(data) - 1) if data[i] == 0xFF and 0xD0 <= data[i + 1] <= 0xD7]
    assert len(rst) > 8
    d = bytearray(data)
    d[rst[3] + 1] = 0xD0 + (d[rst[3] + 1] - 0xD0 + 2) % 8
    with pytest.raises(ic.ImageCheckError, match="restart marker 5 out of sequence"):
        ic.check_jpeg(bytes(d))
    with pytest.raises(ic.ImageCheckError, match="truncated JPEG"):
        ic.check_jpeg(data[:len(data) // 2])
    with pytest.raises(ic.ImageCheckError, match="corrupt JPEG data"):
        ic.check_jpeg(data[:-2] + b"\x00" * 3 + data[-2:])  # bytes the decoder would not use


def test_png_crc_and_truncation(road):
    data = cv2.imencode(".png", road)[1].tobytes()
    ic.check_png(data)
    d = bytearray(data)
    d[len(d) // 2] ^= 0x10
    with pytest.raises(ic.ImageCheckError, match="CRC mismatch in the b'IDAT' chunk"):
        ic.check_png(bytes(d))
    with pytest.raises(ic.ImageCheckError, match="truncated PNG"):
        ic.check_png(data[:-20])


# ------------------------------------------------------------------------------ property-based
FUZZ = settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def _only_protocol_errors(message) -> None:
    try:
        decode_telemetry(message)
    except ProtocolError as e:
        assert str(e) and "\n" not in str(e)


@FUZZ
@given(st.one_of(st.text(), st.binary()))
def test_decode_telemetry_raises_only_protocol_errors_on_any_input(message):
    _only_protocol_errors(message)


def _tiny_jpeg() -> bytes:
    return jpeg(np.random.default_rng(1).integers(0, 256, (24, 24, 3), dtype=np.uint8), 80)


TINY = _tiny_jpeg()
scalars = st.one_of(st.none(), st.booleans(), st.integers(), st.integers(min_value=10 ** 300),
                    st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=12),
                    st.sampled_from(["1.0", "-0.5", "nan", "inf", "1e400", "1_0", " 2 ", ""]))
json_values = st.recursive(scalars, lambda inner: st.one_of(st.lists(inner, max_size=3),
                                                          st.dictionaries(st.text(max_size=4), inner, max_size=3)),
                           max_leaves=8)


@st.composite
def images(draw):
    """base64 strings: real JPEG bytes with edits, truncations and headers of other sizes, or junk."""
    kind = draw(st.sampled_from(["mutated", "truncated", "resized", "junk", "text"]))
    if kind == "text":
        return draw(st.text(max_size=40))
    if kind == "junk":
        data = b"\xff\xd8\xff" + draw(st.binary(max_size=300))
    elif kind == "truncated":
        data = TINY[:draw(st.integers(0, len(TINY)))]
    elif kind == "resized":
        data = with_size(TINY, draw(st.integers(0, 65535)), draw(st.integers(0, 65535)))
    else:
        d = bytearray(TINY)
        for _ in range(draw(st.integers(1, 6))):
            d[draw(st.integers(0, len(d) - 1))] = draw(st.integers(0, 255))
        data = bytes(d)
    return base64.b64encode(data).decode()


@FUZZ
@given(st.dictionaries(st.one_of(st.sampled_from(TELEMETRY_KEYS + ("time",)), st.text(max_size=6)),
                       st.one_of(json_values, images()), max_size=7))
def test_decode_telemetry_raises_only_protocol_errors_on_json_objects(fields):
    _only_protocol_errors(json.dumps(fields))


@FUZZ
@given(images(), st.sampled_from(["0.0", 0, "7.25", "1e3"]))
def test_decode_telemetry_with_every_field_present(image, number):
    message = json.dumps({"steering_angle": number, "throttle": number, "speed": number, "image": image})
    _only_protocol_errors(message)


@FUZZ
@given(images())
def test_decode_image_gives_an_image_or_a_protocol_error(image):
    try:
        img = decode_image(image)
    except ProtocolError:
        return
    assert img.dtype == np.uint8 and img.ndim == 3 and img.shape[2] == 3 and min(img.shape[:2]) >= 16


def test_progressive_scan_damage_is_refused_now_that_libjpeg_reads_the_codes(road):
    """Progressive JPEGs used to get the marker checks only: damage in their scans that libjpeg
    warns about is refused as well, and a clean one passes."""
    good = jpeg(road, 85, progressive=1)
    ic.check_jpeg(good)
    files = [corrupt(good, seed=300 + k, n=12, at=0.2 + 0.06 * k) for k in range(10)]
    warned = [any(w in text for w in LIBJPEG_WARNS) for text in libjpeg_warnings(files)]
    assert sum(warned) >= 3
    for f, w in zip(files, warned):
        if w:
            with pytest.raises(ic.ImageCheckError, match="corrupt JPEG data"):
                ic.check_jpeg(f)


def test_cmyk_and_greyscale_jpegs_pass_the_libjpeg_read():
    """libjpeg gives CMYK files only as CMYK: the check must ask for that, not refuse them."""
    import io

    from PIL import Image
    arr = np.random.default_rng(2).integers(0, 256, (40, 56, 4), dtype=np.uint8)
    for mode, pixels in (("CMYK", arr), ("RGB", arr[:, :, :3]), ("L", arr[:, :, 0])):
        buf = io.BytesIO()
        Image.fromarray(pixels, mode).save(buf, "JPEG", quality=80)
        data = buf.getvalue()
        ic.check_jpeg(data)
        assert ic.decode(data).shape == (40, 56, 3), mode


def test_the_checked_read_is_opencvs_picture(road):
    """decode() returns libjpeg's checked read of a JPEG: pixel for pixel what cv2.imdecode gives
    (subsampling, progressive, grey); a file with an EXIF orientation is OpenCV's, turned."""
    import io

    from PIL import Image
    for src in (road, cv2.cvtColor(road, cv2.COLOR_BGR2GRAY)):
        for flags in ({}, {"sampling_factor": cv2.IMWRITE_JPEG_SAMPLING_FACTOR_420}, {"progressive": 1},
                      {"sampling_factor": cv2.IMWRITE_JPEG_SAMPLING_FACTOR_422, "rst_interval": 3}):
            if src.ndim == 2 and "sampling_factor" in flags:
                continue
            data = jpeg(src, 75, **flags)
            assert ic.check_jpeg(data, bgr=True) is not None
            assert np.array_equal(ic.decode(data), cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR))
    exif = Image.Exif()
    exif[0x0112] = 6  # orientation: turned 90 degrees
    buf = io.BytesIO()
    Image.fromarray(road[:, :, ::-1]).save(buf, "JPEG", quality=80, exif=exif.tobytes())
    data = buf.getvalue()
    assert ic.check_jpeg(data, bgr=True) is None
    assert ic.decode(data).shape == (320, 240, 3)  # OpenCV applied the tag
