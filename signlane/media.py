"""Reading images and videos from users' files, with one clear error per bad input.

Every image comes out as uint8 (H, W, 3) BGR whatever it was on disk (grayscale, RGBA,
16-bit); problems raise `MediaError` whose message names the file and what is wrong.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

import cv2
import numpy as np

from signlane.imagecheck import DEFAULT_MAX_PIXELS, ImageCheckError, check_pixels, decode

# FFmpeg's own messages ("moov atom not found") would add noise lines beside ours
os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")

IMAGE_EXT = {".jpg", ".jpeg", ".png", ".bmp", ".tif", ".tiff", ".webp"}
VIDEO_EXT = {".mp4", ".avi", ".mov", ".mkv", ".m4v", ".webm", ".mpg", ".mpeg"}
MIN_SIDE = 16


class MediaError(Exception):
    """A user's file that cannot be used: str(e) is one line naming the file."""


@dataclass(frozen=True)
class Source:
    path: Path
    kind: str  # image | video


def expand(paths: list[str | Path]) -> tuple[list[Source], list[str]]:
    """Files and folders -> sources (folders: their images and videos, sorted) and error lines."""
    sources, errors = [], []
    for raw in paths:
        p = Path(raw)
        if p.is_dir():
            try:
                found = [q for q in sorted(p.iterdir()) if q.suffix.lower() in IMAGE_EXT | VIDEO_EXT and q.is_file()]
            except OSError as e:  # unreadable folder (or an entry in it): that input fails, the rest goes on
                errors.append(f"{p}: cannot list the folder ({e.strerror or e})")
                continue
            if not found:
                errors.append(f"{p}: folder has no images or videos ({', '.join(sorted(IMAGE_EXT | VIDEO_EXT))})")
            sources += [Source(q, _kind(q)) for q in found]
        elif p.is_file():
            sources.append(Source(p, _kind(p)))
        else:
            errors.append(f"{p}: no such file or folder")
    return sources, errors


def _kind(p: Path) -> str:
    return "video" if p.suffix.lower() in VIDEO_EXT else "image"


def to_bgr8(img: np.ndarray, name: str) -> np.ndarray:
    """Any decoded image -> uint8 (H, W, 3) BGR."""
    if img.dtype == np.uint16:
        img = (img >> 8).astype(np.uint8)
    elif img.dtype in (np.float32, np.float64):
        img = np.clip(img * (255.0 if img.max() <= 1.0 else 1.0), 0, 255).astype(np.uint8)
    elif img.dtype != np.uint8:
        raise MediaError(f"{name}: unsupported pixel type {img.dtype}")
    if img.ndim == 2:
        img = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
    elif img.ndim == 3 and img.shape[2] == 4:
        img = cv2.cvtColor(img, cv2.COLOR_BGRA2BGR)
    elif img.ndim == 3 and img.shape[2] == 1:
        img = cv2.cvtColor(img[:, :, 0], cv2.COLOR_GRAY2BGR)
    elif not (img.ndim == 3 and img.shape[2] == 3):
        raise MediaError(f"{name}: unsupported image shape {img.shape}")
    h, w = img.shape[:2]
    if min(h, w) < MIN_SIDE:
        raise MediaError(f"{name}: image is {w}x{h}; need at least {MIN_SIDE}x{MIN_SIDE}")
    return np.ascontiguousarray(img)


def read_image(path: str | Path, max_pixels: int = DEFAULT_MAX_PIXELS) -> np.ndarray:
    """Read an image file as uint8 BGR; images over `max_pixels`, truncated or corrupt JPEG and
    PNG data (signlane/imagecheck.py) and undecodable files raise MediaError."""
    p = Path(path)
    try:
        data = p.read_bytes()
    except OSError as e:
        raise MediaError(f"{p}: cannot read ({e.strerror})") from None
    if not data:
        raise MediaError(f"{p}: empty file")
    try:  # libjpeg would decode a truncated or corrupt file with a warning; refuse it instead
        img = decode(data, max_pixels, cv2.IMREAD_UNCHANGED)
    except ImageCheckError as e:
        raise MediaError(f"{p}: {e}") from None
    return to_bgr8(img, str(p))


# containers whose frame count comes from an index of every frame; others (Matroska, WebM, MPEG)
# estimate it from the duration, which may be a frame or two off
INDEXED_VIDEO_EXT = {".avi", ".mp4", ".mov", ".m4v"}


def iter_video(path: str | Path, max_pixels: int = DEFAULT_MAX_PIXELS) -> Iterator[np.ndarray]:
    """Frames of a video as uint8 BGR; raises MediaError if it cannot be opened, its frames are
    over `max_pixels`, it has no frames, or (after its last readable frame) it ends before the
    frame count its container gives."""
    p = Path(path)
    cap = cv2.VideoCapture(str(p))
    if not cap.isOpened():
        raise MediaError(f"{p}: cannot open video (corrupt, empty or unsupported codec)")
    try:
        w, h = int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
        if w > 0 and h > 0:
            try:
                check_pixels(w, h, max_pixels)
            except ImageCheckError as e:
                raise MediaError(f"{p}: video frame: {e}") from None
        expected = int(cap.get(cv2.CAP_PROP_FRAME_COUNT) or 0)
        n = 0
        while True:
            ok, frame = cap.read()
            if not ok:
                break
            n += 1
            yield to_bgr8(frame, f"{p} frame {n - 1}")
        if n == 0:
            raise MediaError(f"{p}: video has no readable frames")
        slack = 0 if p.suffix.lower() in INDEXED_VIDEO_EXT else max(1, expected // 50)
        if expected - n > slack:
            raise MediaError(f"{p}: video ended after {n} of the {expected} frames its container lists "
                             "(truncated or corrupt)")
    finally:
        cap.release()


def iter_frames(source: Source, every: int = 1,
                max_pixels: int = DEFAULT_MAX_PIXELS) -> Iterator[tuple[int, np.ndarray]]:
    """(frame index, uint8 BGR) of an image source (index 0) or every `every`-th video frame."""
    if source.kind == "image":
        yield 0, read_image(source.path, max_pixels)
        return
    for i, frame in enumerate(iter_video(source.path, max_pixels)):
        if i % every == 0:
            yield i, frame


def video_info(path: str | Path) -> tuple[float, int]:
    """(fps, frame count or 0 if unknown) of a video."""
    cap = cv2.VideoCapture(str(path))
    try:
        fps = cap.get(cv2.CAP_PROP_FPS) or 20.0
        return (fps if 1.0 <= fps <= 240.0 else 20.0), int(cap.get(cv2.CAP_PROP_FRAME_COUNT) or 0)
    finally:
        cap.release()
