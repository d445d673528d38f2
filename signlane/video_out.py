"""MP4 files people can open anywhere: H.264 (yuv420p, the profile every browser decodes) through
PyAV's FFmpeg, at a capped bitrate, written under a temporary name and renamed when complete.

OpenCV's writer only offers MPEG-4 Part 2 (`mp4v`) from its wheels, which browsers do not play,
at several times the size.
"""
from __future__ import annotations

import os
from fractions import Fraction
from pathlib import Path

import numpy as np

from signlane.fileio import _tmp_name

CRF = 23  # x264's default quality; renders of flat roads need far less than the cap below
BITS_PER_PIXEL = 0.1  # the cap: about 0.9 Mbit/s for 640x480 at 30 frames/s
PRESET = "veryfast"  # encoding beside a simulator on 2 cores: speed over the last few percent of size


class VideoOut:
    """H.264 MP4 writer of uint8 BGR (H, W, 3) frames of one size; the file appears under its
    final name only when closed successfully (`with VideoOut(...) as v:` removes it otherwise).
    Odd frame sizes lose their last row or column (4:2:0 chroma needs even sizes)."""

    def __init__(self, path: str | Path, fps: float, size: tuple[int, int], crf: int = CRF):
        import av
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._tmp = _tmp_name(self.path, keep_ext=True)
        self.size = (int(size[0]), int(size[1]))
        self._even = (self.size[0] - self.size[0] % 2, self.size[1] - self.size[1] % 2)
        if min(self._even) < 2 or not fps > 0:
            raise ValueError(f"{self.path}: a video needs frames of at least 2x2 px and fps > 0, "
                             f"not {self.size[0]}x{self.size[1]} at {fps}")
        cap = max(200_000, int(BITS_PER_PIXEL * self._even[0] * self._even[1] * fps))
        try:
            # faststart: the index goes first, so a browser plays while the file still downloads
            self._box = av.open(str(self._tmp), mode="w", format="mp4", options={"movflags": "+faststart"})
            self._stream = self._box.add_stream("libx264", rate=Fraction(fps).limit_denominator(1001))
            self._stream.width, self._stream.height = self._even
            self._stream.pix_fmt = "yuv420p"
            self._stream.options = {"crf": str(crf), "preset": PRESET, "maxrate": str(cap), "bufsize": str(2 * cap)}
        except (av.FFmpegError, ValueError) as e:
            self._tmp.unlink(missing_ok=True)
            raise OSError(f"{self.path}: cannot open an H.264 video writer ({e})") from None
        self.frames = 0

    def write(self, image: np.ndarray) -> None:
        import av
        if image.shape[:2] != (self.size[1], self.size[0]) or image.ndim != 3:
            raise ValueError(f"{self.path}: frame of shape {image.shape} in a {self.size[0]}x{self.size[1]} video")
        frame = av.VideoFrame.from_ndarray(np.ascontiguousarray(image[:self._even[1], :self._even[0]]),
                                           format="bgr24")
        for packet in self._stream.encode(frame):
            self._box.mux(packet)
        self.frames += 1

    def close(self) -> None:
        """Flush the encoder, finish the file and give it its name (ValueError, and no file, when
        no frame was written: the container is not even created then)."""
        if self.frames == 0:
            self.discard()
            raise ValueError(f"{self.path}: no frames were written, so no video was made")
        try:
            for packet in self._stream.encode():
                self._box.mux(packet)
        finally:
            self._box.close()
        os.replace(self._tmp, self.path)

    def discard(self) -> None:
        try:
            self._box.close()
        finally:
            self._tmp.unlink(missing_ok=True)

    def __enter__(self) -> "VideoOut":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.close()
        else:
            self.discard()
