"""Donkey Car tubs: a signlane drive recording written as donkeycar's tub (the `Tub` of donkeycar
4.x and 5.x, datastore v2), so donkeycar's trainers can learn on signlane's worlds; and a reader.

A tub is a folder:
  images/<index>_<key, / as _>_.jpg  one JPEG per image input and record (0_cam_image_array_.jpg)
  catalog_<n>.catalog             one JSON record per line (keys sorted), at most max_len records
                                  (donkeycar's default 1000): the declared inputs, image inputs
                                  as file names, plus _index, _session_id, _timestamp_ms
  catalog_<n>.catalog_manifest    one JSON line: created_at, line_lengths (each catalog line's
                                  length, newline included), path (the catalog's name), start_index
  manifest.json                   five JSON lines: the inputs, their types, the user metadata,
                                  the manifest metadata (created_at, sessions), the catalog
                                  bookkeeping (paths, current_index, max_len, deleted_indexes)
Nothing here imports donkeycar; the layout is its datastore's, written line for line as it writes it.
"""
from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import IO, Sequence

import cv2
from tqdm import tqdm

from signlane import __version__, imagecheck
from signlane.fileio import atomic_folder
from signlane.sim.protocol import encode_jpeg
from signlane.sim.drive_record import RecordError, Recording, read_recording

DEFAULT_MAX_LEN = 1000  # records per catalog file, as donkeycar's Tub
IMAGES = "images"
MANIFEST = "manifest.json"
TYPES = ("image_array", "float", "int", "str", "boolean")
IMAGE_KEY = "cam/image_array"
JPEG_QUALITY = 75  # what donkeycar's own writes get (PIL's default) for resized frames
# the inputs donkeycar's drive loop records, then the speed the simulator reported
DRIVE_INPUTS = ((IMAGE_KEY, "image_array"), ("user/angle", "float"), ("user/throttle", "float"),
                ("user/mode", "str"))
SPEED_INPUT = ("car/speed", "float")  # metres per second


class TubError(Exception):
    """A tub cannot be written or read; the message names the folder or file and why."""


def image_file_name(index: int, key: str) -> str:
    """donkeycar's name for record `index`'s image of input `key`: 0_cam_image_array_.jpg."""
    return f"{index}_{key.replace('/', '_')}_.jpg"


def _json_line(obj, sort_keys: bool) -> str:
    return json.dumps(obj, allow_nan=False, sort_keys=sort_keys) + "\n"


class TubWriter:
    """Writes a tub into `folder` (new or empty; the caller makes it atomic, see export_drive_tub).

    `write()` takes one record's values by input name, an image input's value as JPEG bytes;
    `close()` ends the last catalog and writes manifest.json. Sessions are donkeycar's
    `<yy-mm-dd>_<n>` ids, one per `new_session()`."""

    def __init__(self, folder: str | Path, inputs: Sequence[tuple[str, str]], metadata: dict | None = None,
                 max_len: int = DEFAULT_MAX_LEN):
        bad = [t for _, t in inputs if t not in TYPES]
        if bad or max_len < 1:
            raise ValueError(f"tub inputs of types {TYPES} and max_len >= 1, not {bad or max_len}")
        self.folder = Path(folder)
        self.inputs = [name for name, _ in inputs]
        self.types = [t for _, t in inputs]
        self._type = dict(inputs)
        self.metadata = dict(metadata or {})
        self.max_len = max_len
        self.created_at = time.time()
        self.sessions: dict = {}
        self.index = 0
        self.catalog_paths: list[str] = []
        self._catalog: IO[str] | None = None
        self._lengths: list[int] = []
        (self.folder / IMAGES).mkdir(parents=True, exist_ok=True)

    def new_session(self, date: str) -> str:
        """A new session id (`date` as yy-mm-dd) for the records that follow."""
        last = self.sessions.get("last_id", -1) + 1
        full = f"{date}_{last}"
        self.sessions = {"all_full_ids": [*self.sessions.get("all_full_ids", []), full],
                         "last_id": last, "last_full_id": full}
        return full

    def write(self, values: dict, session_id: str, timestamp_ms: int) -> None:
        record = {}
        for key, value in values.items():
            kind = self._type.get(key)
            if kind is None:
                raise ValueError(f"{key!r} is not one of the tub's inputs {self.inputs}")
            if value is None:
                continue  # as donkeycar: a missing value is left out of the record
            if kind == "image_array":
                name = image_file_name(self.index, key)
                (self.folder / IMAGES / name).write_bytes(value)
                record[key] = name
            else:
                record[key] = {"float": float, "int": int, "str": str, "boolean": bool}[kind](value)
        record.update(_index=self.index, _session_id=session_id, _timestamp_ms=int(timestamp_ms))
        if self._catalog is None or len(self._lengths) >= self.max_len:
            self._next_catalog()
        line = _json_line(record, sort_keys=True)
        self._catalog.write(line)
        self._lengths.append(len(line))
        self.index += 1

    def _next_catalog(self) -> None:
        self._end_catalog()
        name = f"catalog_{len(self.catalog_paths)}.catalog"
        self.catalog_paths.append(name)
        self._catalog = open(self.folder / name, "w", encoding="utf-8", newline="\n")
        self._lengths = []

    def _end_catalog(self) -> None:
        if self._catalog is None:
            return
        self._catalog.close()
        self._catalog = None
        name = self.catalog_paths[-1]
        meta = {"created_at": self.created_at, "line_lengths": self._lengths, "path": name,
                "start_index": self.index - len(self._lengths)}
        (self.folder / name).with_suffix(".catalog_manifest").write_text(_json_line(meta, True), encoding="utf-8")

    def close(self) -> None:
        if self._catalog is None and not self.catalog_paths:
            self._next_catalog()  # donkeycar's empty tub still has its catalog_0
        self._end_catalog()
        bookkeeping = {"paths": self.catalog_paths, "current_index": self.index, "max_len": self.max_len,
                       "deleted_indexes": []}
        lines = [self.inputs, self.types, self.metadata, {"created_at": self.created_at, "sessions": self.sessions},
                 bookkeeping]
        (self.folder / MANIFEST).write_text("".join(_json_line(x, False) for x in lines), encoding="utf-8")

    def abandon(self) -> None:
        """Close the open catalog without a manifest (the caller discards the folder)."""
        if self._catalog is not None:
            self._catalog.close()
            self._catalog = None

    def __enter__(self) -> "TubWriter":
        return self

    def __exit__(self, exc_type, *exc) -> None:
        self.close() if exc_type is None else self.abandon()


# --- reading -----------------------------------------------------------------------------------
@dataclass(frozen=True)
class Tub:
    """A tub read back: its manifest's five lines and the records (deleted ones left out)."""
    folder: Path
    inputs: tuple[str, ...]
    types: tuple[str, ...]
    metadata: dict
    manifest_metadata: dict
    catalogs: dict  # paths, current_index, max_len, deleted_indexes
    records: tuple[dict, ...]

    def image_path(self, record: dict, key: str = IMAGE_KEY) -> Path:
        return self.folder / IMAGES / record[key]


def _read_lines(path: Path, what: str) -> list[str]:
    try:
        return path.read_text(encoding="utf-8").splitlines(keepends=True)
    except FileNotFoundError:
        raise TubError(f"{path}: missing ({what})") from None
    except (OSError, UnicodeDecodeError) as e:
        raise TubError(f"{path}: unreadable ({e})") from None


def _loads(line: str, path: Path, n: int):
    try:
        return json.loads(line)
    except ValueError:
        raise TubError(f"{path}:{n}: not JSON") from None


def read_tub(folder: str | Path) -> Tub:
    """Read a tub as donkeycar does, checking each catalog against its catalog_manifest (line
    lengths, start index); anything inconsistent raises TubError naming the file."""
    folder = Path(folder)
    path = folder / MANIFEST
    lines = _read_lines(path, "a tub has manifest.json")
    if len(lines) != 5:
        raise TubError(f"{path}: {len(lines)} lines, a tub manifest has 5")
    inputs, types, metadata, manifest_metadata, catalogs = (_loads(x, path, n) for n, x in enumerate(lines, 1))
    if not (isinstance(inputs, list) and isinstance(types, list) and len(inputs) == len(types)):
        raise TubError(f"{path}: the inputs and types lines differ in length")
    deleted = set(catalogs.get("deleted_indexes", []))
    records, start = [], 0
    for name in catalogs.get("paths", []):
        cat_path = folder / name
        cat_lines = _read_lines(cat_path, "listed in manifest.json")
        meta_path = cat_path.with_suffix(".catalog_manifest")
        meta_lines = _read_lines(meta_path, "each catalog has one")
        meta = _loads(meta_lines[0], meta_path, 1) if len(meta_lines) == 1 else None
        if not isinstance(meta, dict) or meta.get("path") != name:
            raise TubError(f"{meta_path}: not one JSON line naming {name}")
        if meta.get("line_lengths") != [len(x) for x in cat_lines] or meta.get("start_index") != start:
            raise TubError(f"{meta_path}: its line lengths or start index do not match {name}")
        for n, line in enumerate(cat_lines, 1):
            rec = _loads(line, cat_path, n)
            if rec.get("_index") not in deleted:
                records.append(rec)
        start += len(cat_lines)
    if start != catalogs.get("current_index"):
        raise TubError(f"{path}: current_index {catalogs.get('current_index')}, but the catalogs hold {start}")
    return Tub(folder, tuple(inputs), tuple(types), metadata, manifest_metadata, catalogs, tuple(records))


# --- export from a drive recording -------------------------------------------------------------
@dataclass(frozen=True)
class TubExport:
    frames: int
    catalogs: int
    sessions: int
    folder: Path


def resize_jpeg(jpeg: bytes, size: tuple[int, int], quality: int = JPEG_QUALITY) -> bytes:
    """JPEG bytes decoded (checked, as every image signlane reads), resized to `size` (W, H; area
    interpolation) and encoded again. Raises ValueError (ImageCheckError) when the bytes are
    not a sound image."""
    img = imagecheck.decode(jpeg)
    return encode_jpeg(cv2.resize(img, size, interpolation=cv2.INTER_AREA), quality)


def _check_out(out: Path, recording: Path, force: bool) -> None:
    out_r, rec_r = out.resolve(), recording.resolve()
    if out_r == rec_r or out_r in rec_r.parents:
        raise TubError(f"{out}: the tub would replace the recording {recording}; choose another --out")
    if out.exists() and not out.is_dir():
        raise TubError(f"{out}: exists and is not a folder")
    if out.is_dir() and any(out.iterdir()) and not force:
        raise TubError(f"{out} is not empty; export into a new or empty folder, or pass --force to replace it")


def _number(frame: dict, *keys: str) -> float | None:
    v = frame
    for k in keys:
        v = v.get(k) if isinstance(v, dict) else None
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        return None
    return float(v)


def _start(manifest: dict) -> datetime:
    """When the recording began (its manifest's `created`); the export's time if it has none."""
    try:
        start = datetime.fromisoformat(manifest["created"])
        return start if start.tzinfo else start.replace(tzinfo=timezone.utc)
    except (KeyError, TypeError, ValueError):
        return datetime.now(timezone.utc)


def export_drive_tub(recording: str | Path, out: str | Path, size: tuple[int, int] | None = None,
                     force: bool = False, max_len: int = DEFAULT_MAX_LEN, progress: bool = True) -> TubExport:
    """Write the drive recording `recording` (`signlane drive --record`) as a Donkey Car tub in
    `out`, atomically (built beside it, then renamed). Each frame is one record: its JPEG as sent
    (resized to `size` if given), user/angle and user/throttle the command the driver sent,
    user/mode "user", car/speed the reported speed (m/s). Each client connection of the
    recording is one session, its frames together in order; _timestamp_ms is the recording's
    start plus the frame's time since its session's first frame. Raises RecordError (the
    recording) or TubError (the output), one line each."""
    rec = read_recording(recording)
    out = Path(out)
    _check_out(out, rec.folder, force)
    if not rec.frames:
        raise TubError(f"{rec.folder}: the recording holds no frames; nothing to export")
    sessions: dict[str, list[dict]] = {}  # by client, in order of first frame: each one's frames together
    for f in rec.frames:
        sessions.setdefault(str(f.get("client")), []).append(f)
    has_speed = any(_number(f, "telemetry", "speed_mps") is not None for f in rec.frames)
    inputs = DRIVE_INPUTS + ((SPEED_INPUT,) if has_speed else ())
    start = _start(rec.manifest)
    metadata = {"source": "signlane drive recording", "recording": str(rec.folder.resolve()),
                "signlane_version": __version__, "image_size": f"{size[0]}x{size[1]}" if size else "as recorded"}
    bar = tqdm(total=len(rec.frames), desc="export tub", unit="frame", disable=not progress, delay=2.0)
    with bar, atomic_folder(out) as tmp, TubWriter(tmp, inputs, metadata, max_len) as tub:
        for frames in sessions.values():
            _write_session(tub, rec, frames, start, size, has_speed, bar)
    return TubExport(tub.index, len(tub.catalog_paths), len(sessions), out)


def _write_session(tub: TubWriter, rec: Recording, frames: list[dict], start: datetime,
                   size: tuple[int, int] | None, has_speed: bool, bar) -> None:
    """One client's frames as one session, stamped from the recording's start plus each frame's
    time since the session's first (never going back)."""
    session = tub.new_session(start.strftime("%y-%m-%d"))
    base_ms = round(start.timestamp() * 1000)
    t0, stamp = None, base_ms
    for f in frames:
        t = _number(f, "t")
        if t is not None:
            t0 = t if t0 is None else t0
            stamp = max(stamp, base_ms + round(1000 * (t - t0)))
        tub.write(_frame_values(rec, f, size, has_speed), session, stamp)
        bar.update()


def _frame_values(rec: Recording, frame: dict, size: tuple[int, int] | None, has_speed: bool) -> dict:
    where = f"{rec.folder}: frame {frame.get('id', frame['image'])}"
    steering, throttle = _number(frame, "command", "steering"), _number(frame, "command", "throttle")
    if steering is None or throttle is None:
        raise RecordError(f"{where}: no numeric command.steering / command.throttle")
    path = rec.image_path(frame)
    try:
        if rec.folder.resolve() not in path.resolve().parents:
            raise ValueError("outside the recording folder")
        jpeg = path.read_bytes()
        if imagecheck.image_format(jpeg) != "jpeg":
            raise ValueError("not a JPEG")
        if size is not None:
            jpeg = resize_jpeg(jpeg, size)
    except (OSError, ValueError) as e:
        raise RecordError(f"{where}: image {frame['image']}: {getattr(e, 'strerror', None) or e}") from None
    values = {IMAGE_KEY: jpeg, "user/angle": steering, "user/throttle": throttle, "user/mode": "user"}
    if has_speed:
        values[SPEED_INPUT[0]] = _number(frame, "telemetry", "speed_mps")
    return values
