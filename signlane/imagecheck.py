"""Image bytes checked before OpenCV decodes them: the size from the header, a pixel limit, and
the integrity of JPEG and PNG data.

OpenCV decodes whatever it is given: a 3 MB JPEG of 12000x12000 px becomes a 430 MB array (and
gigabytes while decoding), and a JPEG whose entropy-coded data is corrupt decodes to a smeared
picture with only a libjpeg warning on stderr. `decode` reads the size from the header without
decoding, refuses images over `max_pixels`, checks the data (JPEG: markers, then every code of every
scan read by libjpeg-turbo itself in a 1/8-scale decode whose warnings are errors, plus a check that
a sequential scan's last byte holds code; PNG: every chunk's CRC) and only then decodes.
Problems raise `ImageCheckError` with one line saying what is wrong (callers add which input).
"""
from __future__ import annotations

import re
import struct
import zlib
from functools import lru_cache

import cv2
import numpy as np
import simplejpeg

DEFAULT_MAX_PIXELS = 4096 * 4096


class ImageCheckError(ValueError):
    """Image bytes that must not be decoded: str(e) is one line, without the input's name."""


# ------------------------------------------------------------------------------------ formats
def image_format(data: bytes) -> str | None:
    """'jpeg', 'png', 'bmp', 'tiff', 'webp' from the leading bytes, or None."""
    if data[:3] == b"\xff\xd8\xff":
        return "jpeg"
    if data[:8] == b"\x89PNG\r\n\x1a\n":
        return "png"
    if data[:2] == b"BM":
        return "bmp"
    if data[:4] in (b"II*\x00", b"MM\x00*"):
        return "tiff"
    if data[:4] == b"RIFF" and data[8:12] == b"WEBP":
        return "webp"
    return None


def header_size(data: bytes) -> tuple[int, int]:
    """(width, height) read from the header, without decoding; ImageCheckError if unreadable."""
    kind = image_format(data)
    if kind is None:
        raise ImageCheckError(f"not an image this reader knows (bytes start {data[:8]!r}; expected a JPEG, PNG, "
                              "BMP, TIFF or WebP)")
    try:
        if kind == "jpeg":
            return _jpeg_frame(data).size
        return {"png": _png_size, "bmp": _bmp_size, "tiff": _tiff_size, "webp": _webp_size}[kind](data)
    except (struct.error, IndexError):
        raise ImageCheckError(f"truncated {kind.upper()} header ({len(data)} bytes)") from None


def check_pixels(width: int, height: int, max_pixels: int = DEFAULT_MAX_PIXELS) -> None:
    if width <= 0 or height <= 0:
        raise ImageCheckError(f"header says the image is {width}x{height} px")
    if width * height > max_pixels:
        raise ImageCheckError(f"image is {width}x{height} px, over the limit of {max_pixels} pixels "
                              f"({_limit_text(max_pixels)})")


def _limit_text(max_pixels: int) -> str:
    side = int(round(max_pixels ** 0.5))
    return f"{side}x{side}" if side * side == max_pixels else f"{max_pixels / 1e6:.1f} MP"


def check_integrity(data: bytes) -> None:
    """JPEG: markers, and every Huffman code of sequential scans; PNG: chunk CRCs and IEND.
    Other formats pass unchecked. ImageCheckError names the first problem."""
    kind = image_format(data)
    if kind == "jpeg":
        check_jpeg(data)
    elif kind == "png":
        check_png(data)


def decode(data: bytes, max_pixels: int = DEFAULT_MAX_PIXELS, flags: int = cv2.IMREAD_COLOR) -> np.ndarray:
    """Checked image bytes -> the array cv2.imdecode(data, flags) gives; ImageCheckError if the
    header is unreadable, the image has more than `max_pixels` pixels, the data is corrupt or
    OpenCV cannot decode it."""
    check_pixels(*header_size(data), max_pixels)
    if image_format(data) == "jpeg" and flags == cv2.IMREAD_COLOR:
        img = check_jpeg(data, bgr=True)  # libjpeg's checked read is the picture, when it can be
        if img is not None:
            return img
    else:
        check_integrity(data)
    try:
        img = cv2.imdecode(np.frombuffer(data, np.uint8), flags)
    except cv2.error:  # some damaged headers make OpenCV raise instead of returning None
        img = None
    if img is None:
        raise ImageCheckError(f"not an image OpenCV can decode ({len(data)} bytes, corrupt or unsupported)")
    return img


# ------------------------------------------------------------------------------------ PNG
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _png_size(data: bytes) -> tuple[int, int]:
    if data[12:16] != b"IHDR":
        raise ImageCheckError("PNG does not start with an IHDR chunk")
    return struct.unpack(">II", data[16:24])


def check_png(data: bytes) -> None:
    """Walk the chunks: each CRC must match, IHDR first, IEND last."""
    try:
        _check_png(data)
    except struct.error:
        raise ImageCheckError("truncated PNG (a chunk header runs past the end)") from None


def _check_png(data: bytes) -> None:
    i, first = len(PNG_SIGNATURE), True
    while True:
        if i + 12 > len(data):
            raise ImageCheckError(f"truncated PNG (no IEND chunk in {len(data)} bytes)")
        length, kind = struct.unpack(">I4s", data[i:i + 8])
        end = i + 12 + length
        if end > len(data):
            raise ImageCheckError(f"truncated PNG ({kind!r} chunk of {length} bytes runs past the end)")
        crc = struct.unpack(">I", data[end - 4:end])[0]
        if zlib.crc32(data[i + 4:end - 4]) != crc:
            raise ImageCheckError(f"corrupt PNG data (CRC mismatch in the {kind!r} chunk at byte {i})")
        if first and kind != b"IHDR":
            raise ImageCheckError("PNG does not start with an IHDR chunk")
        first = False
        if kind == b"IEND":
            return
        i = end


# ------------------------------------------------------------------------------------ BMP, TIFF, WebP
def _bmp_size(data: bytes) -> tuple[int, int]:
    header = struct.unpack("<I", data[14:18])[0]
    if header == 12:  # OS/2 BITMAPCOREHEADER
        w, h = struct.unpack("<HH", data[18:22])
    else:
        w, h = struct.unpack("<ii", data[18:26])
    return w, abs(h)  # a negative height is a top-down bitmap


def _tiff_size(data: bytes) -> tuple[int, int]:
    end = "<" if data[:2] == b"II" else ">"
    ifd = struct.unpack(end + "I", data[4:8])[0]
    count = struct.unpack(end + "H", data[ifd:ifd + 2])[0]
    found = {}
    for k in range(count):
        tag, typ = struct.unpack(end + "HH", data[ifd + 2 + 12 * k:ifd + 6 + 12 * k])
        if tag in (256, 257):  # ImageWidth, ImageLength: SHORT or LONG
            raw = data[ifd + 10 + 12 * k:ifd + 14 + 12 * k]
            found[tag] = struct.unpack(end + ("H" if typ == 3 else "I"), raw[:2] if typ == 3 else raw)[0]
    if len(found) < 2:
        raise ImageCheckError("TIFF header has no image width or length")
    return found[256], found[257]


def _webp_size(data: bytes) -> tuple[int, int]:
    chunk = data[12:16]
    if chunk == b"VP8 ":
        if data[23:26] != b"\x9d\x01\x2a":
            raise ImageCheckError("WebP VP8 frame has no start code")
        w, h = struct.unpack("<HH", data[26:30])
        return w & 0x3FFF, h & 0x3FFF
    if chunk == b"VP8L":
        bits = struct.unpack("<I", data[21:25])[0]
        return (bits & 0x3FFF) + 1, ((bits >> 14) & 0x3FFF) + 1
    if chunk == b"VP8X":
        return int.from_bytes(data[24:27], "little") + 1, int.from_bytes(data[27:30], "little") + 1
    raise ImageCheckError(f"WebP has an unknown first chunk {chunk!r}")


# ------------------------------------------------------------------------------------ JPEG
SOF_MARKERS = {0xC0, 0xC1, 0xC2, 0xC3, 0xC5, 0xC6, 0xC7, 0xC9, 0xCA, 0xCB, 0xCD, 0xCE, 0xCF}
SEQUENTIAL_HUFFMAN = {0xC0, 0xC1}  # baseline and extended sequential: restart markers and trailing bytes checked


class _Frame:
    def __init__(self, marker: int, height: int, width: int, comps: list[tuple[int, int, int]]):
        self.marker, self.height, self.width = marker, height, width
        self.comps = {c: (h, v) for c, h, v in comps}
        self.hmax = max(h for _, h, _ in comps)
        self.vmax = max(v for _, _, v in comps)

    @property
    def size(self) -> tuple[int, int]:
        return self.width, self.height


def _next_segment(data: bytes, i: int) -> tuple[int, int, int]:
    """The marker at byte i (after fill bytes) and its payload (start, end); EOI has none."""
    n = len(data)
    if i < n and data[i] != 0xFF:
        raise ImageCheckError(f"corrupt JPEG data (byte {i} should start a marker)")
    while i < n and data[i] == 0xFF:  # fill bytes before a marker
        i += 1
    if i >= n:
        raise ImageCheckError(f"truncated JPEG (no end-of-image marker in {n} bytes)")
    marker = data[i]
    i += 1
    if marker == 0xD9:
        return marker, i, i
    if marker < 0xC0:
        raise ImageCheckError(f"not a decodable JPEG (byte {i - 1} is 0x{marker:02x}, no marker)")
    if 0xD0 <= marker <= 0xD8:
        raise ImageCheckError(f"corrupt JPEG data (marker 0x{marker:02x} outside a scan at byte {i - 2})")
    if i + 2 > n:
        raise ImageCheckError(f"truncated JPEG (no end-of-image marker in {n} bytes)")
    length = (data[i] << 8) | data[i + 1]
    if length < 2 or i + length > n:
        raise ImageCheckError(f"truncated JPEG (segment 0x{marker:02x} at byte {i - 2} runs past the end)")
    return marker, i + 2, i + length


def _parse_sof(marker: int, seg: bytes) -> _Frame:
    nf = seg[5] if len(seg) >= 6 else 0
    if nf == 0 or len(seg) < 6 + 3 * nf:
        raise ImageCheckError("corrupt JPEG frame header (SOF)")
    height, width = struct.unpack(">HH", seg[1:5])
    comps = [(seg[6 + 3 * k], seg[7 + 3 * k] >> 4, seg[7 + 3 * k] & 15) for k in range(nf)]
    if any(not (1 <= h <= 4 and 1 <= v <= 4) for _, h, v in comps):
        raise ImageCheckError("corrupt JPEG frame header (SOF): a sampling factor outside 1..4")
    if height == 0:
        raise ImageCheckError("JPEG gives its height in a DNL marker, which is not supported")
    return _Frame(marker, height, width, comps)


def _jpeg_frame(data: bytes) -> _Frame:
    """The frame header (size, components), read without touching the entropy-coded data."""
    i = 2
    while True:
        marker, a, i = _next_segment(data, i)
        if marker in SOF_MARKERS:
            return _parse_sof(marker, data[a:i])
        if marker in (0xDA, 0xD9):
            break
    raise ImageCheckError("JPEG has no frame header (SOF) before its first scan")


@lru_cache(maxsize=16)  # cameras use the same few tables on every frame
def _huffman_table(spec: bytes, ac: bool) -> bytes:
    """A DHT table (16 counts + symbols), checked: no more codes of a length than its bits allow,
    DC sizes up to 16. The codes themselves are read by libjpeg (see `_entropy_check`)."""
    counts, symbols = spec[:16], spec[16:]
    code, k = 0, 0
    for length in range(1, 17):
        for _ in range(counts[length - 1]):
            if code >= 1 << length or (not ac and symbols[k] > 16):
                raise ImageCheckError("corrupt JPEG Huffman table (DHT): more codes than bits, or a bad DC size")
            k += 1
            code += 1
        code <<= 1
    return spec


class _Scan:
    def __init__(self, frame: _Frame, seg: bytes, dc: dict, ac: dict):
        ns = seg[0]
        if ns == 0 or len(seg) != 4 + 2 * ns:
            raise ImageCheckError("corrupt JPEG scan header (SOS)")
        sel = [(seg[1 + 2 * k], seg[2 + 2 * k] >> 4, seg[2 + 2 * k] & 15) for k in range(ns)]
        ss, se, a = seg[1 + 2 * ns], seg[2 + 2 * ns], seg[3 + 2 * ns]
        self.sequential = (ss, se, a) == (0, 63, 0)
        blocks = []  # (dc table, ac table) of each block of one MCU, in order
        for c, td, ta in sel:
            if c not in frame.comps:
                raise ImageCheckError(f"JPEG scan names component {c}, which the frame does not have")
            if (td not in dc or ta not in ac) and self.sequential:
                raise ImageCheckError(f"JPEG scan uses a Huffman table that is not defined (DC {td}, AC {ta})")
            h, v = frame.comps[c] if ns > 1 else (1, 1)
            blocks += [(dc.get(td), ac.get(ta))] * (h * v)
        self.blocks = blocks
        if ns > 1:
            self.mcus = -(-frame.width // (8 * frame.hmax)) * -(-frame.height // (8 * frame.vmax))
        else:
            h, v = frame.comps[sel[0][0]]
            cw = -(-frame.width * h // frame.hmax)
            ch = -(-frame.height * v // frame.vmax)
            self.mcus = -(-cw // 8) * -(-ch // 8)


def _scan_end(data: bytes, i: int) -> tuple[int, list[tuple[int, int]]]:
    """Where the entropy-coded data starting at i ends (the next marker), and its restart
    markers as (byte offset, number 0-7)."""
    rst = []
    j = data.find(b"\xff", i)
    while True:
        if j < 0 or j + 1 >= len(data):
            raise ImageCheckError(f"truncated JPEG (scan data runs to the end of the file, {len(data)} bytes)")
        nxt = data[j + 1]
        if nxt == 0x00:
            j = data.find(b"\xff", j + 2)
        elif 0xD0 <= nxt <= 0xD7:
            rst.append((j, nxt - 0xD0))
            j = data.find(b"\xff", j + 2)
        else:
            return j, rst


def check_jpeg(data: bytes, bgr: bool = False) -> np.ndarray | None:
    """Markers in order, a frame header before the first scan, an end-of-image marker, restart
    markers in sequence (sequential Huffman JPEGs: what cameras and simulators send); every code of
    every scan as libjpeg reads it (anything it would warn about); no whole byte of junk after a
    sequential JPEG's last code. ImageCheckError names the first problem.

    With bgr=True libjpeg's read is a whole decode, returned as uint8 (H, W, 3) BGR, the pixels
    cv2.imdecode gives (one libjpeg-turbo, its default IDCT and upsampling), where that decode is
    cv2.imdecode's: not for CMYK files, nor for files with EXIF data (OpenCV turns the picture by
    its orientation tag). Else None, as without it."""
    try:
        return _check_jpeg(data, bgr)
    except (struct.error, IndexError):  # a segment shorter than the fields it must hold
        raise ImageCheckError("corrupt JPEG data (a header segment is shorter than its fields)") from None


def _check_jpeg(data: bytes, bgr: bool) -> np.ndarray | None:
    scans: list[int] = []
    ends: list[int] = []
    try:
        sequential, exif = _check_markers(data, scans, ends)
    except ImageCheckError:
        if scans:  # damage inside a scan's data (a stray 0xFF, lost bytes) reads as a marker problem
            _entropy_check(data, scans, False)  # after it: libjpeg's words for it come first
        raise
    img = _entropy_check(data, scans, bgr and not exif)
    if sequential:
        _whole_bytes_used(data, scans[-1], ends[-1])
    return img


def _check_markers(data: bytes, scans: list[int], ends: list[int]) -> tuple[bool, bool]:
    """The marker walk; appends where each scan's data starts to `scans` and where it ends to
    `ends`. Returns (a sequential Huffman JPEG?, has EXIF data?)."""
    frame, dc, ac, restart, exif = None, {}, {}, 0, False
    i = 2
    while True:
        marker, a, b = _next_segment(data, i)
        seg, i = data[a:b], b
        if marker in SOF_MARKERS:
            frame = _parse_sof(marker, seg)
        elif marker == 0xC4:
            _parse_dht(seg, dc, ac)
        elif marker == 0xE1 and seg.startswith(b"Exif"):
            exif = True
        elif marker == 0xDD:
            if len(seg) != 2:
                raise ImageCheckError("corrupt JPEG restart interval (DRI)")
            restart = (seg[0] << 8) | seg[1]
        elif marker == 0xDA:
            if frame is None:
                raise ImageCheckError("JPEG has no frame header (SOF) before its first scan")
            end, rst = _scan_end(data, b)
            if frame.marker in SEQUENTIAL_HUFFMAN:
                _check_scan(data, b, end, rst, _Scan(frame, seg, dc, ac), restart)
            scans.append(b)
            ends.append(end)
            i = end
        elif marker == 0xD9:
            if not scans:
                raise ImageCheckError("JPEG ends before its first scan (no image data)")
            return frame.marker in SEQUENTIAL_HUFFMAN, exif


_EXTRANEOUS = re.compile(r"(\d+) extraneous bytes before marker 0x([0-9a-f]{2})")


def _whole_bytes_used(data: bytes, start: int, end: int) -> None:
    """Does the last scan use its data up to its last byte? libjpeg reads a few bytes ahead, so
    a few bytes of junk before the end-of-image marker escape its count of extraneous bytes.
    Without its last byte, a scan that needs that byte's bits makes libjpeg run out of data
    (it warns only when a code needs bits past the end); if libjpeg does not, that byte (and
    any after it) held no code: extraneous data."""
    if end - start < 2:
        return
    try:
        _decode_eighth(data[:end - 1] + data[end:])
    except ValueError:
        return
    raise ImageCheckError(f"corrupt JPEG data (at least 1 extraneous bytes in the scan at byte {start})")


def _decode_eighth(data: bytes, bgr: bool = False) -> np.ndarray | None:
    """libjpeg's strict read (a warning raises ValueError): the whole picture in BGR when `bgr`
    and the file is not CMYK or YCCK, else at 1/8 scale, read and dropped."""
    kind = simplejpeg.decode_jpeg_header(data)[2]
    cmyk = kind in ("CMYK", "YCCK")  # libjpeg gives these as CMYK only
    if bgr and not cmyk:
        return simplejpeg.decode_jpeg(data, colorspace="BGR", strict=True)
    # grey output needs only the luma's inverse DCT
    simplejpeg.decode_jpeg(data, colorspace="CMYK" if cmyk else "GRAY", min_factor=8, min_width=1, min_height=1,
                           strict=True)
    return None


def _entropy_check(data: bytes, scans: list[int], bgr: bool) -> np.ndarray | None:
    """Every Huffman (or arithmetic) code of every scan, read by libjpeg itself: a decode at
    1/8 scale (libjpeg-turbo's DCT scaling: the entropy decoder reads every code, the inverse DCT
    makes one pixel a block) in which a libjpeg warning is an error, so what libjpeg would
    warn about on stderr is refused here and libjpeg's stderr stays quiet. `scans`: the byte
    offsets of the scans' data, to say where. With bgr, the whole decode (see _decode_eighth)."""
    try:
        return _decode_eighth(data, bgr)
    except ValueError as e:
        text = str(e).strip().splitlines()[0] if str(e).strip() else "undecodable"
        m = _EXTRANEOUS.search(text)
        if m:  # the data a scan's last block leaves over before the next marker
            at = scans[-1] if m[2] == "d9" else scans[0]
            raise ImageCheckError(f"corrupt JPEG data ({m[1]} extraneous bytes in the scan at byte {at})") from None
        if text.lower().startswith("corrupt jpeg data: "):
            text = text[len("corrupt jpeg data: "):]
        raise ImageCheckError(f"corrupt JPEG data ({text[:120]}, in the scan at byte {scans[0]})") from None


def _parse_dht(seg: bytes, dc: dict, ac: dict) -> None:
    i = 0
    while i < len(seg):
        if i + 17 > len(seg):
            raise ImageCheckError("corrupt JPEG Huffman table (DHT)")
        tc, th = seg[i] >> 4, seg[i] & 15
        n = sum(seg[i + 1:i + 17])
        spec = seg[i + 1:i + 17 + n]
        if tc > 1 or th > 3 or len(spec) != 16 + n or n > 256:
            raise ImageCheckError("corrupt JPEG Huffman table (DHT)")
        (ac if tc else dc)[th] = _huffman_table(bytes(spec), bool(tc))
        i += 17 + n


def _check_scan(data: bytes, start: int, end: int, rst: list[tuple[int, int]], scan: _Scan, restart: int) -> None:
    if not scan.sequential:
        raise ImageCheckError("corrupt JPEG scan header (a sequential JPEG with a progressive scan)")
    intervals = -(-scan.mcus // restart) if restart else 1
    if len(rst) != intervals - 1:
        raise ImageCheckError(f"corrupt JPEG data (the scan at byte {start} has {len(rst)} restart markers, "
                              f"expected {intervals - 1})")
    for k in range(1, intervals):
        if rst[k - 1][1] != (k - 1) % 8:
            raise ImageCheckError(f"corrupt JPEG data (restart marker {rst[k - 1][1]} out of sequence at byte "
                                  f"{rst[k - 1][0]})")
