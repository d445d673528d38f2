"""Sign-crop dataset in torchvision ImageFolder layout: `<class>/<id>.png`, one folder per
class of SIGN_CLASSES (including `unknown`), uint8 BGR PNGs of `crop` x `crop` pixels.

Two phases, each a pure function of (seed, index) so any worker count writes the same bytes:
1. frames: rendered 640x480 frames give crops of their ground-truth signs (`f<frame>_<k>.png`)
   and unknown crops (distractors, red/blue colour regions, background), the unknowns capped
   by a per-frame quota that sums to SCENE_UNKNOWN_SHARE of the unknown target;
2. sprites: each class is topped up to its target with sprite renders on rendered backgrounds
   (`s<index>.png`), and UNKNOWN_SPRITE_SHARE of the unknown target always comes from sprite
   hard negatives; how many of each follows from phase 1's counts, so it is fixed too.
"""
from __future__ import annotations

import json
import logging
from collections import Counter
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from signlane_data import sign_crops as sc
from signlane_data.common import (PARTIAL, atomic_imwrite, atomic_write_json, file_intact, partial_dir, prepare_output,
                                  run_indexed, sample_id, write_manifest)
from signlane.fileio import atomic_write_text
from signlane.splits import write_split_files
from signlane.world.art import SIGN_CLASSES
from signlane.world.render import Sample
from signlane.world.sampling import FrameSampler, SamplerConfig

log = logging.getLogger(__name__)

FRAME_SIZE = (640, 480)  # signs are 12-60 px here, as on the car's camera
SCENE_UNKNOWN_SHARE = 0.7  # the rest of the unknowns: distractor sprites and plain background
# frames alone often fill the unknown target with scene proposals; this share of it is always
# added as sprite hard negatives (sign-like discs, rectangles, triangles) under the
# sprites' wide viewpoint and camera randomisation, which frames of our own renderer never reach
UNKNOWN_SPRITE_SHARE = 0.5
SPRITES_PER_BG = 8  # sprites that share one background frame (rendering it is the cost)


def class_targets(n: int, unknown_fraction: float) -> dict[str, int]:
    """Crops wanted per class: `unknown_fraction` of n unknown, the rest split evenly."""
    signs = SIGN_CLASSES[1:]
    per = int(round(n * (1.0 - unknown_fraction) / len(signs)))
    return {"unknown": max(0, n - per * len(signs)), **{c: per for c in signs}}


def unknown_quota(i: int, frames: int, total: int) -> int:
    """Frame i's share of `total` unknown crops; the shares of frames 0..frames-1 sum to total."""
    return (i + 1) * total // frames - i * total // frames


@lru_cache(maxsize=2)
def _sampler(seed: int, config: SamplerConfig) -> FrameSampler:
    return FrameSampler(seed, config)  # one per process: it caches the current track


@lru_cache(maxsize=1)
def _frame(seed: int, config: SamplerConfig, index: int) -> Sample:
    return _sampler(seed, config).sample(index)  # consecutive sprites share a background


@dataclass(frozen=True)
class FrameCropJob:
    """Phase 1, frame i: renders it, writes its crops, then a record listing them."""

    out: str
    frames: int
    seed: int
    sampler: SamplerConfig
    crop: int
    unknown_total: int

    def _record(self, i: int) -> Path:
        return Path(self.out, PARTIAL, "frames", f"{sample_id(i, self.frames)}.json")

    def done(self, i: int) -> bool:
        rec = self._record(i)
        if not rec.exists() or not file_intact(rec):
            return False
        return all(Path(self.out, f).exists() and file_intact(Path(self.out, f))
                   for _, f in json.loads(rec.read_text())["crops"])

    def __call__(self, i: int) -> None:
        rng = np.random.default_rng([self.seed, i, 11])
        crops = sc.frame_crops(_sampler(self.seed, self.sampler).sample(i), rng,
                               unknown_quota(i, self.frames, self.unknown_total), self.crop)
        listed = []
        for k, (label, img) in enumerate(crops):
            rel = f"{label}/f{sample_id(i, self.frames)}_{k:02d}.png"
            atomic_imwrite(Path(self.out, rel), img)
            listed.append([label, rel])
        partial_dir(self.out, "frames")
        atomic_write_json(self._record(i), {"crops": listed})

    def counts(self) -> Counter:
        """Crops per class written by phase 1 (all frames must be done)."""
        return Counter(label for i in range(self.frames)
                       for label, _ in json.loads(self._record(i).read_text())["crops"])


@dataclass(frozen=True)
class SpriteJob:
    """Phase 2, sprite u: class plan[u], on a background from frame first_bg + u // SPRITES_PER_BG."""

    out: str
    seed: int
    sampler: SamplerConfig
    crop: int
    plan: tuple[str, ...]
    first_bg: int

    def path(self, u: int) -> Path:
        return Path(self.out, self.plan[u], f"s{sample_id(u, len(self.plan))}.png")

    def done(self, u: int) -> bool:
        return self.path(u).exists() and file_intact(self.path(u))

    def __call__(self, u: int) -> None:
        rng = np.random.default_rng([self.seed, u, 12])
        bg = _frame(self.seed, self.sampler, self.first_bg + u // SPRITES_PER_BG)
        atomic_imwrite(self.path(u), sc.sprite_crop(self.plan[u], rng, bg, self.crop))


def signs_config(n: int, seed: int, crop: int, unknown_fraction: float, frames: int,
                 sampler: SamplerConfig) -> dict:
    """The resolved options that determine the dataset's bytes (saved in the manifest)."""
    return {"n": int(n), "seed": int(seed), "crop": int(crop), "unknown_fraction": float(unknown_fraction),
            "frames": int(frames), "sampler": sampler.recorded(), "classes": list(SIGN_CLASSES),
            "targets": class_targets(n, unknown_fraction), "scene_unknown_share": SCENE_UNKNOWN_SHARE,
            "unknown_sprite_share": UNKNOWN_SPRITE_SHARE,
            "unknown_kind_weights": sc.UNKNOWN_KIND_WEIGHTS, "stop_words": sc.STOP_WORDS,
            "sign_min_px": sc.SIGN_MIN_PX, "max_occluded": sc.MAX_OCCLUDED, "max_truncated": sc.MAX_TRUNCATED,
            "min_face_contrast": sc.MIN_FACE_CONTRAST, "min_symbol_survival": sc.MIN_SYMBOL_SURVIVAL,
            "pad_max": sc.PAD_MAX, "shift_max": sc.SHIFT_MAX, "sprite_px": list(sc.SPRITE_PX),
            "proposal_iou": sc.PROPOSAL_IOU, "yaw_max_deg": sc.YAW_MAX_DEG, "occlude_prob": sc.OCCLUDE_PROB}


def generate_signs(out: str | Path, n: int, seed: int, crop: int = 48, workers: int = 1, resume: bool = False,
                   preview: bool = False, unknown_fraction: float = 0.3, frames: int | None = None,
                   style: str = "painted") -> dict:
    """Write about `n` sign crops (`class_targets`; more where frames alone give more) to `out`
    in ImageFolder layout and return the manifest, whose `counts` holds the crops per class.
    `frames` (default n // 4) rendered frames supply the real crops. Raises DatasetError if
    `out` is not empty and is not this dataset or, without `resume`, holds an unfinished run."""
    if n < 1 or crop < 8 or not 0.0 <= unknown_fraction <= 1.0:
        raise ValueError(f"need n >= 1, crop >= 8 and 0 <= unknown_fraction <= 1 (got {n}, {crop}, "
                         f"{unknown_fraction})")
    out = Path(out)
    frames = max(1, n // 4) if frames is None else int(frames)
    sampler = SamplerConfig(width=FRAME_SIZE[0], height=FRAME_SIZE[1], effects="mixed", randomise=True,
                            focus="signs", style=style)
    config = signs_config(n, seed, crop, unknown_fraction, frames, sampler)
    manifest = prepare_output(out, "signs", config, resume)
    if manifest is None:
        manifest = _generate(out, n, seed, crop, workers, unknown_fraction, frames, sampler, config)
    if preview:
        from signlane_data.preview import write_sign_preview
        write_sign_preview(out)
    return manifest


def _generate(out: Path, n: int, seed: int, crop: int, workers: int, unknown_fraction: float, frames: int,
              sampler: SamplerConfig, config: dict) -> dict:
    for c in SIGN_CLASSES:
        (out / c).mkdir(parents=True, exist_ok=True)
    targets = class_targets(n, unknown_fraction)
    scene_unknown = int(round(targets["unknown"] * SCENE_UNKNOWN_SHARE))
    job = FrameCropJob(str(out), frames, seed, sampler, crop, scene_unknown)
    run_indexed(frames, job, workers, desc="sign crops: frames", done_fn=job.done, chunk=sampler.frames_per_track)
    from_frames = job.counts()
    wanted = {c: max(0, targets[c] - from_frames[c]) for c in SIGN_CLASSES}
    wanted["unknown"] = max(wanted["unknown"], int(round(targets["unknown"] * UNKNOWN_SPRITE_SHARE)))
    plan = tuple(c for c in SIGN_CLASSES for _ in range(wanted[c]))
    sprites = SpriteJob(str(out), seed, sampler, crop, plan, first_bg=frames)
    run_indexed(len(plan), sprites, workers, desc="sign crops: sprites", done_fn=sprites.done,
                chunk=SPRITES_PER_BG * sampler.frames_per_track)
    counts = {c: len(list((out / c).glob("*.png"))) for c in SIGN_CLASSES}
    sources = {"frames": {c: from_frames[c] for c in SIGN_CLASSES}, "sprites": dict(Counter(plan))}
    log.info("%s: wrote %d sign crops %s", out, sum(counts.values()), counts)
    # the conventions other tools read: class index order, and the split `signlane train` uses
    atomic_write_text(out / "classes.txt", "".join(c + "\n" for c in SIGN_CLASSES))
    split = write_split_files(out, (f"{c}/{f.name}" for c in SIGN_CLASSES for f in (out / c).glob("*.png")))
    return write_manifest(out, "signs", seed, counts, config, sources=sources, split=split,
                          class_order=list(SIGN_CLASSES))
