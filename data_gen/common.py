"""Machinery shared by the dataset generators: atomic writes, resumable parallel runs, manifests.

A dataset folder is complete iff it holds `manifest.json`, which is written last. Everything a
run needs only while it is unfinished (its options, per-sample records) lives in `.partial/`,
removed once the manifest is written. Every file is written under a temporary name ending in
`.tmp` (or `.tmp.<ext>` where a library needs the extension) and renamed into place, so a killed
run leaves whole files or stray temporaries, never half files; resuming deletes the temporaries.
"""
from __future__ import annotations

import json
import logging
import multiprocessing as mp
import shutil
from collections.abc import Callable
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import cv2
from tqdm import tqdm

import signlane
from signlane.imagecheck import ImageCheckError, check_integrity, header_size
# atomic writes live in the runtime package; re-exported here for the generators
from signlane.fileio import (TMP_SUFFIX, atomic_imwrite, atomic_write_bytes,  # noqa: F401
                             atomic_write_json, atomic_write_text)

log = logging.getLogger(__name__)

MANIFEST = "manifest.json"
PARTIAL = ".partial"  # scratch of an unfinished run; gone once the dataset is complete
DEFAULT_CHUNK = 25  # = SamplerConfig.frames_per_track: a chunk renders one track, built once


class DatasetError(Exception):
    """A dataset folder cannot be used as asked; the message says why and what to do."""




def remove_stray_tmp(root: str | Path) -> int:
    """Delete temporaries a killed run left under `root`; return how many."""
    count = 0
    for p in Path(root).rglob(f"*{TMP_SUFFIX}*"):
        if p.is_file() and (p.name.endswith(TMP_SUFFIX) or f"{TMP_SUFFIX}." in p.name):
            p.unlink()
            count += 1
    if count:
        log.info("removed %d stray temporary file(s) from %s", count, root)
    return count


def file_intact(path: str | Path) -> bool:
    """True when `path` holds a whole file that reads back: an image whose header and data check
    out (JPEG markers and codes, PNG CRCs: signlane.imagecheck), JSON that parses, anything else
    non-empty. Atomic writes never leave half files, but a crash before the disk flushed them can
    leave empty or damaged ones under their final names; resume makes those samples again."""
    p = Path(path)
    try:
        data = p.read_bytes()
    except OSError:
        return False
    problem = "empty file" if not data else ""
    try:
        if not problem and p.suffix.lower() in (".jpg", ".jpeg", ".png"):
            header_size(data)
            check_integrity(data)
        elif not problem and p.suffix.lower() == ".json":
            json.loads(data)
    except (ImageCheckError, ValueError) as e:
        problem = str(e)
    if problem:
        log.warning("%s: %s; making it again", p, problem)
    return not problem


def sample_id(i: int, n: int) -> str:
    """Zero-padded id, at least 6 digits (`000123`), so ids sort in index order."""
    return str(i).zfill(max(6, len(str(max(n - 1, 0)))))


# --------------------------------------------------------------------------- parallel runs
_WORK_FN: Callable[[int], Any] | None = None


def _init_worker(work_fn: Callable[[int], Any]) -> None:
    global _WORK_FN
    cv2.setNumThreads(1)  # the processes are the parallelism; OpenCV threads would oversubscribe
    _WORK_FN = work_fn


def _run_chunk(chunk: list[int]) -> list[tuple[int, Any]]:
    assert _WORK_FN is not None
    return [(i, _WORK_FN(i)) for i in chunk]


def chunked(indices: list[int], chunk: int) -> list[list[int]]:
    """Split sorted `indices` into contiguous runs that never cross a multiple of `chunk`, so a
    chunk stays inside one sampler track group whatever was already done."""
    out: list[list[int]] = []
    for i in indices:
        if out and out[-1][-1] == i - 1 and i % chunk != 0:
            out[-1].append(i)
        else:
            out.append([i])
    return out


def run_indexed(n: int, work_fn: Callable[[int], Any], workers: int = 1, desc: str = "",
                done_fn: Callable[[int], bool] | None = None, chunk: int = DEFAULT_CHUNK) -> dict[int, Any]:
    """Call `work_fn(i)` for every i in 0..n-1 for which `done_fn(i)` is not true.

    `work_fn` must be picklable (a module-level function or an instance of a module-level
    class); with `workers` > 1 each spawned process gets its own copy and builds its own
    sampler. Output must be a pure function of i, which makes the files the same whatever
    `workers` is. Returns {i: work_fn(i)} for the indices run now (not the skipped ones)."""
    todo = [i for i in range(n) if done_fn is None or not done_fn(i)]
    chunks = chunked(todo, max(1, chunk))
    if 1 < len(todo) and len(chunks) < workers:
        # too few for the track-sized chunks: every worker gets a share (a track built twice)
        chunks = chunked(todo, -(-len(todo) // workers))
    results: dict[int, Any] = {}
    with tqdm(total=n, initial=n - len(todo), desc=desc, unit="it", dynamic_ncols=True) as bar:
        if workers <= 1 or len(chunks) <= 1:
            for c in chunks:
                for i in c:
                    results[i] = work_fn(i)
                    bar.update(1)
            return results
        # spawn, not fork: forking a parent whose OpenCV thread pool is running can deadlock
        ctx = mp.get_context("spawn")
        with ctx.Pool(min(workers, len(chunks)), _init_worker, (work_fn,)) as pool:
            for part in pool.imap_unordered(_run_chunk, chunks):
                results.update(part)
                bar.update(len(part))
    return results


# --------------------------------------------------------------------------- dataset folders
def jsonable(obj: Any) -> Any:
    """`obj` as plain JSON types (tuples become lists), for comparing configs."""
    return json.loads(json.dumps(obj))


def read_manifest(out: str | Path) -> dict | None:
    """The manifest of a complete dataset in `out`, or None if there is none."""
    p = Path(out) / MANIFEST
    if not p.exists():
        return None
    try:
        return json.loads(p.read_text())
    except (OSError, json.JSONDecodeError) as e:
        raise DatasetError(f"{p}: unreadable manifest ({e}); delete it to finish the run with --resume") from None


def _differences(a: dict, b: dict) -> list[str]:
    return sorted(k for k in set(a) | set(b) if a.get(k) != b.get(k))


def prepare_output(out: str | Path, kind: str, config: dict, resume: bool) -> dict | None:
    """Make `out` ready for a run of generator `kind` with `config`.

    Returns the existing manifest if `out` already holds this exact dataset (nothing to do),
    else None after creating the folders and recording the options in `.partial/config.json`.
    Raises DatasetError for a folder that holds something else, or an unfinished run when
    `resume` is false."""
    out = Path(out)
    config = jsonable(config)
    generator = f"signlane.data_gen.{kind}"
    manifest = read_manifest(out)
    if manifest is not None:
        if manifest.get("generator") == generator and manifest.get("config") == config:
            log.info("%s: dataset already complete (%s); nothing to do", out, MANIFEST)
            shutil.rmtree(out / PARTIAL, ignore_errors=True)  # a run killed while tidying up
            return manifest
        diff = _differences(manifest.get("config", {}), config)
        raise DatasetError(f"{out} already holds a complete dataset ({manifest.get('generator')}) made with "
                           f"different options ({', '.join(diff) or 'generator'}); choose an empty folder")
    if out.exists() and any(out.iterdir()):
        if not resume:
            raise DatasetError(f"{out} is not empty and holds no finished dataset (no {MANIFEST}): pass "
                               f"--resume to finish an interrupted run there, or choose an empty folder")
        _check_partial(out, generator, config)
        remove_stray_tmp(out)
    (out / PARTIAL).mkdir(parents=True, exist_ok=True)
    atomic_write_json(out / PARTIAL / "config.json", {"generator": generator, "config": config})
    return None


def _check_partial(out: Path, generator: str, config: dict) -> None:
    rec_path = out / PARTIAL / "config.json"
    if not rec_path.exists():
        # e.g. a finished dataset whose manifest was deleted: every sample is checked anyway
        log.warning("%s: no record of the interrupted run's options; assuming they match", out)
        return
    try:
        rec = json.loads(rec_path.read_text())
    except (OSError, json.JSONDecodeError):
        log.warning("%s: unreadable %s; assuming the options match", out, rec_path)
        return
    if rec.get("generator") != generator or rec.get("config") != config:
        diff = _differences(rec.get("config", {}), config)
        raise DatasetError(f"{out} holds an interrupted {rec.get('generator')} run with different options "
                           f"({', '.join(diff) or 'generator'}); resume with the same options or choose an "
                           f"empty folder")
    log.info("%s: resuming an interrupted run", out)


def write_manifest(out: str | Path, kind: str, seed: int, counts: dict, config: dict, **extra: Any) -> dict:
    """Write `manifest.json` (last, atomically, fsynced), remove `.partial/`, return the manifest."""
    out = Path(out)
    manifest = {"generator": f"signlane.data_gen.{kind}", "version": signlane.__version__, "seed": int(seed),
                "counts": counts, "config": jsonable(config), **extra,
                "created": datetime.now(timezone.utc).isoformat(timespec="seconds")}
    atomic_write_json(out / MANIFEST, manifest, fsync=True)
    shutil.rmtree(out / PARTIAL, ignore_errors=True)
    return manifest


def partial_dir(out: str | Path, *parts: str) -> Path:
    """A scratch folder `.partial/<parts>` of an unfinished run (created)."""
    p = Path(out, PARTIAL, *parts)
    p.mkdir(parents=True, exist_ok=True)
    return p
