"""Where `signlane run` gets its frames: a camera (OpenCV VideoCapture: a device index or a
stream URL) or a video file played at its own frame rate.

Each source reads on its own thread into a one-frame slot: the drive loop always gets the newest
frame, a frame the loop was too busy for is dropped (as the drive server skips a simulator's
backlog), and a camera that stops delivering (unplugged, a stream that hangs) shows up as a
timeout in `next`, never as a loop stuck inside a read.
"""
from __future__ import annotations

import logging
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from signlane.imagecheck import DEFAULT_MAX_PIXELS
from signlane.media import MediaError, iter_video, to_bgr8, video_info

log = logging.getLogger("signlane.run")
CAMERA_RETRY_S = 0.05  # a failed camera read is tried again after this long


class SourceError(ValueError):
    """A camera or video that cannot be used: str(e) is one line naming it."""


@dataclass(frozen=True)
class Captured:
    image: np.ndarray  # uint8 (H, W, 3) BGR
    t: float  # seconds: the video's own clock, or the monotonic clock at capture
    index: int  # the frame's number in the source (gaps: frames the loop had no time for)
    arrived: float  # time.perf_counter() when it was read


class _Slot:
    """The newest frame, handed over between the reader thread and the loop."""

    def __init__(self):
        self._cond = threading.Condition()
        self._frame: Captured | None = None
        self._ended: str | None = None
        self.read = 0

    def put(self, frame: Captured) -> None:
        with self._cond:
            self._frame = frame
            self.read += 1
            self._cond.notify()

    def end(self, why: str) -> None:
        with self._cond:
            self._ended = why
            self._cond.notify()

    def take(self, timeout_s: float) -> Captured | str | None:
        """The newest unread frame; the reason the source ended (str) once it has and nothing is
        left; None after timeout_s without a frame."""
        with self._cond:
            self._cond.wait_for(lambda: self._frame is not None or self._ended is not None, timeout_s)
            frame, self._frame = self._frame, None
            if frame is not None:
                return frame
            return self._ended


class _ThreadedSource:
    name = "source"

    def __init__(self):
        self._slot = _Slot()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._guarded, daemon=True, name="frames")

    def start(self) -> "_ThreadedSource":
        self._thread.start()
        return self

    def _guarded(self) -> None:
        try:
            self._read()
        except MediaError as e:
            self._slot.end(str(e))
        except Exception as e:  # a reader bug ends the stream (and stops the car), not silently
            self._slot.end(f"{self.name}: {type(e).__name__}: {e}")

    def next(self, timeout_s: float) -> Captured | str | None:
        return self._slot.take(timeout_s)

    @property
    def frames_read(self) -> int:
        return self._slot.read

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=1.0)  # a capture stuck in a read stays behind (daemon thread)


class VideoSource(_ThreadedSource):
    """A video file in real time: frame i is handed over at start + i / fps and carries t = i / fps."""

    def __init__(self, path: str | Path, max_pixels: int = DEFAULT_MAX_PIXELS, fps: float | None = None):
        super().__init__()
        self.path = Path(path)
        self.name = f"video {self.path}"
        if not self.path.exists():
            raise SourceError(f"video {self.path}: no such file")
        if not self.path.is_file():
            raise SourceError(f"video {self.path}: not a file")
        cap = cv2.VideoCapture(str(self.path))
        ok = cap.isOpened() and cap.read()[0]
        cap.release()
        if not ok:
            raise SourceError(f"video {self.path}: cannot read a frame from it (not a video, corrupt, or an "
                              "unsupported codec)")
        self.fps = fps or video_info(self.path)[0]
        self.max_pixels = max_pixels

    def _read(self) -> None:
        start = time.perf_counter()
        for i, image in enumerate(iter_video(self.path, self.max_pixels)):
            if self._stop.is_set():
                return
            due = start + i / self.fps
            wait = due - time.perf_counter()
            if wait > 0 and self._stop.wait(wait):
                return
            self._slot.put(Captured(image, i / self.fps, i, time.perf_counter()))
        self._slot.end(f"end of {self.name}")


class CameraSource(_ThreadedSource):
    """An OpenCV capture: `spec` a device index ("0") or a URL/pipeline string; `capture` an
    already opened object with read() -> (ok, image) and release() (tests, other drivers)."""

    def __init__(self, spec: str = "0", capture=None):
        super().__init__()
        self.spec = spec
        self.name = f"camera {spec}"
        if capture is None:
            target = int(spec) if spec.strip().isdigit() else spec
            level = cv2.utils.logging.getLogLevel()
            cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_ERROR)  # our line says it, not OpenCV's warnings
            try:
                capture = cv2.VideoCapture(target)
            finally:
                cv2.utils.logging.setLogLevel(level)
            if not capture.isOpened():
                capture.release()
                what = "no such device, or it is in use" if isinstance(target, int) else \
                    "cannot open that URL or pipeline"
                raise SourceError(f"camera {spec}: cannot open it ({what})")
        self.capture = capture

    def _read(self) -> None:
        i = 0
        try:
            while not self._stop.is_set():
                ok, image = self.capture.read()
                if not ok or image is None:  # a dropped frame or a camera gone: the loop's timeout decides
                    self._stop.wait(CAMERA_RETRY_S)
                    continue
                image = to_bgr8(image, f"{self.name} frame {i}")
                self._slot.put(Captured(image, time.monotonic(), i, time.perf_counter()))
                i += 1
        finally:
            self.capture.release()
