"""Atomic file writes: a temporary in the same folder, then os.replace, so an interrupted
process never leaves a half-written file under the final name."""
from __future__ import annotations

import json
import os
import shutil
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any, Iterable, Iterator

import cv2
import numpy as np

TMP_SUFFIX = ".tmp"


def _tmp_name(path: Path, keep_ext: bool = False) -> Path:
    # pid in the name: two processes never share a temporary, even if both write one path
    tag = f".{path.name}.{os.getpid()}{TMP_SUFFIX}"
    return path.with_name(tag + path.suffix if keep_ext else tag)


def atomic_write_bytes(path: str | Path, data: bytes, fsync: bool = False) -> None:
    """Write `data` to `path` via a temporary in the same folder and os.replace.

    `fsync` also survives power loss; it is slow, so only the manifest asks for it."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = _tmp_name(path)
    try:
        with open(tmp, "wb") as f:
            f.write(data)
            if fsync:
                f.flush()
                os.fsync(f.fileno())
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


def atomic_write_text(path: str | Path, text: str, fsync: bool = False) -> None:
    """UTF-8 text version of :func:`atomic_write_bytes`."""
    atomic_write_bytes(path, text.encode("utf-8"), fsync)


def atomic_write_json(path: str | Path, obj: Any, fsync: bool = False, pretty: bool = True) -> None:
    """JSON (keys in the order given), written atomically: indented for people, or compact on one
    line (`pretty=False`: several times faster, as indenting disables the C encoder)."""
    text = json.dumps(obj, indent=2) if pretty else json.dumps(obj, separators=(",", ":"))
    atomic_write_text(path, text + "\n", fsync)


def atomic_imwrite(path: str | Path, img: np.ndarray, params: Iterable[int] = ()) -> None:
    """Encode `img` (uint8 (H, W) grey or (H, W, 3) BGR, OpenCV order) by the path's extension
    (cv2.imencode with `params`, e.g. [cv2.IMWRITE_JPEG_QUALITY, 95]) and write it atomically."""
    path = Path(path)
    ok, buf = cv2.imencode(path.suffix, img, list(params))
    if not ok:
        raise OSError(f"{path}: OpenCV could not encode a {img.dtype} {img.shape} image")
    atomic_write_bytes(path, buf.tobytes())


@contextmanager
def atomic_open_text(path: str | Path) -> Iterator[IO[str]]:
    """A text file written under a temporary name in the same folder and renamed onto `path` when
    the block ends without an exception (then the temporary is removed instead)."""
    path = Path(path)
    tmp = _tmp_name(path)
    f = open(tmp, "w", encoding="utf-8")
    try:
        yield f
        f.close()
        os.replace(tmp, path)
    finally:
        f.close()
        if tmp.exists():
            tmp.unlink()


@contextmanager
def atomic_folder(path: str | Path) -> Iterator[Path]:
    """A folder filled under a temporary name beside `path` and renamed onto it when the block ends
    without an exception (else the temporary is removed). Whatever stood at `path` (the caller has
    decided it may go) is replaced: moved aside, the new folder renamed in, the old one deleted."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = _tmp_name(path)
    if tmp.exists():
        shutil.rmtree(tmp)
    tmp.mkdir()
    try:
        yield tmp
        old = path.with_name(f".{path.name}.{os.getpid()}.old")
        if path.exists():
            os.replace(path, old)
        try:
            os.replace(tmp, path)
        except OSError:
            if old.exists():  # put the old folder back rather than leave neither
                os.replace(old, path)
            raise
        if old.exists():
            shutil.rmtree(old)
    finally:
        if tmp.exists():
            shutil.rmtree(tmp)
