"""The identity of a training set: a hash of what training reads, not of when it was written.

A dataset's manifest carries its `created` time, so hashing it gave byte-identical data different
hashes. This hashes every data file's relative path and bytes instead; files a person looks at
(the manifest, contact sheets) and unfinished work (`.partial/`, temp names) are left out, so the
same seed gives the same hash however often and wherever it is generated.
"""
from __future__ import annotations

import hashlib
from pathlib import Path

NOT_DATA = {"manifest.json", "preview.png", "sheet.png", "rejected.png"}  # top-level files for people
CHUNK = 1 << 20


def data_files(root: Path) -> list[Path]:
    """The files of one dataset folder that training can read, in a stable order."""
    files = []
    for p in root.rglob("*"):
        rel = p.relative_to(root)
        if not p.is_file() or any(part.startswith(".") for part in rel.parts):
            continue
        if len(rel.parts) == 1 and rel.name in NOT_DATA:
            continue
        files.append(p)
    return sorted(files, key=lambda p: p.relative_to(root).as_posix())


def content_hash(roots: list[str | Path]) -> str:
    """16 hex digits over the data files of every root (order of roots does not matter; a
    root's own folder name does not either, so a moved or renamed copy hashes the same)."""
    per_root = []
    for root in map(Path, roots):
        if not root.is_dir():
            raise ValueError(f"{root}: not a dataset folder")
        h = hashlib.sha256()
        for f in data_files(root):
            h.update(f.relative_to(root).as_posix().encode() + b"\0")
            h.update(str(f.stat().st_size).encode() + b"\0")
            with f.open("rb") as fh:
                while chunk := fh.read(CHUNK):
                    h.update(chunk)
        per_root.append(h.hexdigest())
    total = hashlib.sha256("\n".join(sorted(per_root)).encode())
    return total.hexdigest()[:16]
