"""What the drive server writes to disk: a driving dataset (`--record DIR`) and annotated frames
(`--show-every N`). All writing happens on one background thread (see `DiskWriter`), never on
the thread that answers the simulator.

A recording is a folder a person can open and a learner can read:
  images/<id>.jpg   the frame exactly as the simulator sent it (its JPEG bytes, not re-encoded)
  drive.jsonl       one object per driven frame: telemetry in SI units (wheel_deg, pedal,
                    speed_mps, time when sent), the command sent, what perception saw, the
                    teacher's own command ("teacher": the label, which differs from "command"
                    where the applied steering was perturbed on purpose) and the planner's
                    "desire" (the exit it chose, or the way its course turns with the lane
                    lost: left/straight/right; `signlane.pilot.desire_of`)
  manifest.json     written last, on a clean shutdown: counts, the resolved config and, from the
                    simulator (`signlane sim --record`, `signlane gen pilot`), "drive": the track,
                    style, looks and perturbation. As for every signlane dataset, a folder is
                    complete iff it holds manifest.json.
The drive server (`signlane drive --record`), `signlane sim --record` and `signlane gen pilot`
all write this one layout; `signlane train pilot` and `signlane eval pilot` read it.
Each image is written atomically before its JSONL line, so every line names a whole file.
`read_recording` reads a complete one back (`signlane export-drive`, signlane/tub.py).
"""
from __future__ import annotations

import json
import logging
import os
import threading
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Callable

import cv2

from signlane import __version__
from signlane.config import Config
from signlane.fileio import atomic_write_bytes, atomic_write_json
from signlane.sim.protocol import Telemetry
from signlane.types import Command, Perception

log = logging.getLogger("signlane.drive")

FRAMES_FILE = "drive.jsonl"
MANIFEST = "manifest.json"


class RecordError(Exception):
    """The record folder cannot be used; the message says why."""


def _round(v: float, nd: int) -> float:
    return round(float(v), nd)


def frame_record(frame_id: str, client: int, tel: Telemetry, perception: Perception, sent: Command,
                 teacher: Command | None = None, extra: dict | None = None) -> dict:
    """The JSONL object of one driven frame. `sent` holds the values actually sent (clipped);
    `teacher` the driver's own command where a perturbation changed what was sent (the label
    either way); `extra` more keys (e.g. the simulator's ground truth)."""
    from signlane.pilot import desire_of
    h, w = tel.image_bgr.shape[:2]
    lane = perception.lane
    teacher = teacher or sent
    tel_d = {"wheel_deg": tel.wheel_deg, "pedal": tel.pedal, "speed_mps": _round(tel.speed_mps, 5)}
    if tel.time is not None:
        tel_d["time"] = tel.time
    return {"id": frame_id, "image": f"images/{frame_id}.jpg", "width": int(w), "height": int(h),
            "client": client, "t": _round(perception.frame.t, 4), "telemetry": tel_d,
            "steering": _round(teacher.steering, 4),  # the label a steering learner reads, as in lane datasets
            "command": {"steering": _round(sent.steering, 4), "throttle": _round(sent.throttle, 4),
                        "state": sent.state},
            "teacher": {"steering": _round(teacher.steering, 4), "throttle": _round(teacher.throttle, 4),
                        "state": teacher.state},
            "desire": desire_of(teacher.state, teacher.steering),
            "lane": {"method": lane.method, "found": bool(lane.found), "offset": _round(lane.offset, 4),
                     "heading": _round(lane.heading, 5), "curvature": _round(lane.curvature, 6),
                     "confidence": _round(lane.confidence, 3)},
            "signs": [{"label": s.label, "score": _round(s.score, 4), "box": [int(v) for v in s.box]}
                      for s in perception.signs],
            "timing_ms": {k: _round(v, 3) for k, v in perception.timing_ms.items()}, **(extra or {})}


@dataclass(frozen=True)
class Recording:
    """A complete recording read back: its folder, manifest and frame objects in file order."""
    folder: Path
    manifest: dict
    frames: tuple[dict, ...]

    def image_path(self, frame: dict) -> Path:
        return self.folder / frame["image"]


def read_recording(folder: str | Path) -> Recording:
    """Read a `--record` folder; a missing or incomplete one (no manifest.json yet: the server
    writes it last) or a malformed line raises RecordError naming it."""
    folder = Path(folder)
    if not folder.is_dir():
        raise RecordError(f"{folder}: no such recording folder")
    if not (folder / MANIFEST).is_file():
        raise RecordError(f"{folder}: incomplete recording (no {MANIFEST}; the drive server writes it last, "
                          "on a clean exit)")
    try:
        manifest = json.loads((folder / MANIFEST).read_text(encoding="utf-8"))
        lines = (folder / FRAMES_FILE).read_text(encoding="utf-8").splitlines()
    except FileNotFoundError:
        raise RecordError(f"{folder}: not a drive recording (no {FRAMES_FILE})") from None
    except (OSError, UnicodeDecodeError, ValueError) as e:
        raise RecordError(f"{folder}: unreadable recording ({e})") from None
    if not isinstance(manifest, dict) or manifest.get("generator", "signlane.drive") != "signlane.drive":
        raise RecordError(f"{folder}: not a drive recording (its {MANIFEST} is not signlane.drive's)")
    frames = []
    for n, line in enumerate(lines, 1):
        if not line.strip():
            continue
        try:
            frame = json.loads(line)
        except ValueError:
            frame = None
        if not isinstance(frame, dict) or not isinstance(frame.get("image"), str):
            raise RecordError(f"{folder / FRAMES_FILE}:{n}: not a frame object")
        frames.append(frame)
    return Recording(folder, manifest, tuple(frames))


def recording_folders(root: str | Path) -> list[Path]:
    """The recordings a folder holds: itself (a drive.jsonl beside its manifest) or, for `gen
    pilot` output or any folder of recordings, every complete one below it, sorted."""
    root = Path(root)
    if (root / FRAMES_FILE).is_file():
        return [root]
    return sorted(p.parent for p in root.rglob(FRAMES_FILE) if (p.parent / MANIFEST).is_file())


class Recorder:
    """Writes a driving dataset; used from the DiskWriter thread only."""

    def __init__(self, out: str | Path, config: Config, drive: dict | None = None):
        self.out = Path(out)
        self.drive = drive  # what the simulator knows of the drive (track, style, looks), for the manifest
        if self.out.exists() and any(self.out.iterdir()):
            raise RecordError(f"{self.out} is not empty; record into a new or empty folder")
        self.config = config
        self.frames = 0
        self.clients: set[int] = set()
        self.started = datetime.now(timezone.utc).isoformat(timespec="seconds")
        try:
            (self.out / "images").mkdir(parents=True, exist_ok=True)
            # one write() per line on an O_APPEND file: a killed server leaves whole lines
            self._fd = os.open(self.out / FRAMES_FILE, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
        except OSError as e:
            raise RecordError(f"{self.out}: cannot record there ({e.strerror or e})") from None

    def write(self, frame_id: str, client: int, jpeg: bytes, tel: Telemetry, perception: Perception,
              sent: Command, teacher: Command | None = None, extra: dict | None = None) -> None:
        if jpeg[:2] != b"\xff\xd8":  # a PNG or other image OpenCV decoded: store it as the JPEG it claims
            ok, buf = cv2.imencode(".jpg", tel.image_bgr, [cv2.IMWRITE_JPEG_QUALITY, 95])
            jpeg = buf.tobytes() if ok else jpeg
        atomic_write_bytes(self.out / "images" / f"{frame_id}.jpg", jpeg)
        line = json.dumps(frame_record(frame_id, client, tel, perception, sent, teacher, extra),
                          separators=(",", ":"))
        os.write(self._fd, (line + "\n").encode("utf-8"))
        self.frames += 1
        self.clients.add(client)

    def close(self) -> None:
        if self._fd < 0:
            return
        os.close(self._fd)
        self._fd = -1
        atomic_write_json(self.out / MANIFEST, {
            "generator": "signlane.drive", "version": __version__, "seed": None,
            "created": self.started, "finished": datetime.now(timezone.utc).isoformat(timespec="seconds"),
            "counts": {"frames": self.frames, "clients": len(self.clients)},
            "files": {"frames": FRAMES_FILE, "images": "images/<id>.jpg"},
            "config": self.config.to_dict(), **({"drive": self.drive} if self.drive else {})}, fsync=True)
        log.info("recorded %d frames from %d client(s) in %s", self.frames, len(self.clients), self.out)


class Shower:
    """Writes every `every`-th driven frame, annotated (lane, signs, HUD), as <dir>/<id>.jpg."""

    def __init__(self, out: str | Path, every: int):
        self.out = Path(out)
        self.out.mkdir(parents=True, exist_ok=True)
        self.every = max(1, int(every))

    def wants(self, processed: int) -> bool:
        return processed % self.every == 0

    def write(self, frame_id: str, speed: float, perception: Perception, sent: Command) -> None:
        from signlane.draw import draw_hud, write_image
        from signlane.infer import annotate  # the same overlay `signlane infer` draws
        img = annotate(perception, sent)
        h = img.shape[0]
        draw_hud(img, [f"{frame_id}  speed {speed:.2f}"], origin=(4, max(0, h - 26)))
        write_image(self.out / f"{frame_id}.jpg", img)


class DiskWriter:
    """One background thread for disk writes with a bounded backlog: when the disk falls behind,
    new writes are dropped (and counted) rather than queued without end."""

    def __init__(self, max_pending: int = 64):
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="drive-disk")
        self._lock = threading.Lock()
        self._pending = 0
        self.max_pending = max_pending
        self.dropped = 0

    def submit(self, fn: Callable[..., None], *args) -> bool:
        with self._lock:
            if self._pending >= self.max_pending:
                self.dropped += 1
                return False
            self._pending += 1
        self._pool.submit(self._run, fn, *args)
        return True

    def _run(self, fn: Callable[..., None], *args) -> None:
        try:
            fn(*args)
        except Exception as e:  # a full disk must not stop the driving
            log.error("cannot write %s: %s", getattr(fn, "__qualname__", fn), e)
        finally:
            with self._lock:
                self._pending -= 1

    def close(self) -> None:
        """Finish every queued write."""
        self._pool.shutdown(wait=True)


def sent_command(answer: str, state: str) -> Command:
    """The Command as it went on the wire (clipped, NaN-free), from the encoded answer."""
    d = json.loads(answer)
    return Command(float(d["steering"]), float(d["throttle"]), state)
