"""Recall / false proposals / speed of the colour proposals on seeded rendered frames.

`python -m signlane.signs.eval_proposals --n 500 --out runs/proposals` prints a table of the
robust and published variants on the normal and hard sets and writes `proposals.csv` and
`recall_by_size.png` (drawn with OpenCV; matplotlib is not a runtime dependency).

Counting rules:
* eligible sign: ground-truth box >= `min_size` px in both w and h and occluded <= 0.5;
* a sign is recalled when a proposal matches it at box IoU >= 0.5 (greedy one-to-one, best IoU first);
* a proposal is false when it is matched to no sign (small ones are matched too) and overlaps no
  small or hidden sign at IoU >= 0.3: finding a sign too small to count is no mistake, and the
  IoU of a few-pixel box is noisy, hence the lower bar. A second proposal on one sign is false.
"""
from __future__ import annotations

import argparse
import csv
import logging
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterable, Sequence

import cv2
import numpy as np

from signlane.signs.proposals import ProposalParams, box_iou, propose
from signlane.types import SignDetection

log = logging.getLogger(__name__)
MATCH_IOU = 0.5
IGNORE_IOU = 0.3
MAX_OCCLUDED = 0.5
SIZE_BINS = (0, 8, 12, 16, 20, 24, 32, 48, 64, 96, 10_000)  # px, by min(w, h) of the true box
VARIANTS = {"robust": ProposalParams, "published": ProposalParams.published}


@dataclass
class Tally:
    """Running counts over frames."""

    frames: int = 0
    signs: int = 0
    recalled: int = 0
    false: int = 0
    proposals: int = 0
    wrong_color: int = 0
    ms: list[float] = field(default_factory=list)
    size_hits: dict[int, list[int]] = field(default_factory=dict)  # bin index -> [found, total]

    def add_frame(self, signs: Sequence, props: Sequence[SignDetection], min_size: int, ms: float) -> None:
        """One frame: `signs` are SignTruth-like (label, box, occluded), `props` propose()'s output."""
        self.frames += 1
        self.proposals += len(props)
        self.ms.append(ms)
        visible = [s for s in signs if s.occluded <= MAX_OCCLUDED]
        eligible = {i for i, s in enumerate(visible) if min(s.box[2], s.box[3]) >= min_size}
        found = _match(visible, props)  # small ones are matched too: the size curve wants them
        for i, s in enumerate(visible):
            hit = self.size_hits.setdefault(_size_bin(s.box), [0, 0])
            hit[0] += i in found
            hit[1] += 1
        self.signs += len(eligible)
        for i in eligible & found.keys():
            self.recalled += 1
            self.wrong_color += props[found[i]].color != _sign_color(visible[i].label)
        ignored = [s.box for i, s in enumerate(visible) if i not in eligible]
        ignored += [s.box for s in signs if s.occluded > MAX_OCCLUDED]
        used = set(found.values())
        for j, p in enumerate(props):
            if j not in used and not any(box_iou(p.box, b) >= IGNORE_IOU for b in ignored):
                self.false += 1

    def summary(self) -> dict:
        return {"frames": self.frames, "signs": self.signs, "recalled": self.recalled,
                "recall": self.recalled / max(self.signs, 1), "false_per_frame": self.false / max(self.frames, 1),
                "proposals_per_frame": self.proposals / max(self.frames, 1), "wrong_color": self.wrong_color,
                "ms_median": float(np.median(self.ms)) if self.ms else 0.0,
                "by_size": [(SIZE_BINS[b], SIZE_BINS[b + 1], f, t) for b, (f, t) in sorted(self.size_hits.items())]}


def _size_bin(box: Sequence[int]) -> int:
    return int(np.searchsorted(SIZE_BINS, min(box[2], box[3]), side="right")) - 1


def _sign_color(label: str) -> str:
    return "red" if label in ("stop", "no_left", "no_right") else "blue"


def _match(signs: Sequence, props: Sequence[SignDetection]) -> dict[int, int]:
    """Greedy one-to-one matching at IoU >= MATCH_IOU: sign index -> proposal index."""
    pairs = sorted(((box_iou(s.box, p.box), i, j) for i, s in enumerate(signs) for j, p in enumerate(props)),
                   reverse=True)
    out: dict[int, int] = {}
    used: set[int] = set()
    for iou, i, j in pairs:
        if iou < MATCH_IOU:
            break
        if i not in out and j not in used:
            out[i] = j
            used.add(j)
    return out


def evaluate_frames(frames: Iterable[tuple[np.ndarray, Sequence]], params: ProposalParams,
                    min_size: int = 20) -> dict:
    """Score propose() on (uint8 BGR image, SignTruth-like signs) pairs; see the module docstring."""
    return evaluate_variants(frames, {"": params}, min_size)[""]


def evaluate_variants(frames: Iterable[tuple[np.ndarray, Sequence]], variants: dict[str, ProposalParams],
                      min_size: int = 20) -> dict[str, dict]:
    """evaluate_frames() for several parameter sets in one pass over the frames (rendering costs
    more than proposing)."""
    tallies = {name: Tally() for name in variants}
    for image, signs in frames:
        for name, params in variants.items():
            t0 = time.perf_counter()
            props = propose(image, params)
            tallies[name].add_frame(signs, props, min_size, 1000.0 * (time.perf_counter() - t0))
    return {name: t.summary() for name, t in tallies.items()}


def rendered_frames(n: int, seed: int, hard: bool, width: int, height: int, progress: bool = False,
                    focus: str = "none"):
    """The seeded test set: (image, truth signs) for frames 0..n-1 of FrameSampler(seed).
    focus="signs" asks the sampler for frames placed before signs (more signs per frame)."""
    from signlane.world.sampling import FrameSampler, SamplerConfig  # the runtime never needs the world

    extra = {} if focus == "none" else {"focus": focus}  # the default set needs no newer sampler option
    cfg = SamplerConfig(width=width, height=height, effects="hard" if hard else "normal", randomise=True,
                        looks_strength=2.0 if hard else 1.0, **extra)
    sampler = FrameSampler(seed, cfg)
    idx = range(n)
    if progress:
        from tqdm import tqdm
        idx = tqdm(idx, desc=f"{'hard' if hard else 'normal'} frames", leave=False)
    for i in idx:
        s = sampler.sample(i)
        yield s.image, s.truth.signs


def eval_proposals(n: int = 500, seed: int = 1000, hard: bool = False, variant: str = "robust",
                   min_size: int = 20, width: int = 640, height: int = 480, progress: bool = False,
                   focus: str = "none") -> dict:
    """Recall at IoU 0.5 of signs >= min_size px, false proposals per frame and median ms per frame of
    one variant ("robust" or "published") on n seeded rendered frames (normal or hard effects)."""
    return eval_many(n, seed, hard, (variant,), min_size, width, height, progress, focus)[0]


def eval_many(n: int = 500, seed: int = 1000, hard: bool = False, variants: Sequence[str] = tuple(VARIANTS),
              min_size: int = 20, width: int = 640, height: int = 480, progress: bool = False,
              focus: str = "none") -> list[dict]:
    """eval_proposals() of several variants on one rendering of the set."""
    unknown = [v for v in variants if v not in VARIANTS]
    if unknown:
        raise ValueError(f"unknown variant {unknown[0]!r}; expected one of {sorted(VARIANTS)}")
    frames = rendered_frames(n, seed, hard, width, height, progress, focus)
    results = evaluate_variants(frames, {v: VARIANTS[v]() for v in variants}, min_size)
    rows = []
    for v in variants:
        out = results[v]
        name = ("hard" if hard else "normal") + ("" if focus == "none" else f"/{focus}")
        out.update(variant=v, set=name, seed=seed, size=f"{width}x{height}")
        if out["signs"] < 200:
            log.warning("%s/%s: only %d eligible signs in %d frames; recall is a rough estimate",
                        v, out["set"], out["signs"], n)
        rows.append(out)
    return rows


def format_table(rows: Sequence[dict]) -> str:
    """The table of eval_proposals() results."""
    from signlane.tables import table
    return table(["variant", "set", "frames", "signs", "recall", "false/fr", "props/fr", "ms"],
                 [[r["variant"], r["set"], r["frames"], r["signs"], f"{100 * r['recall']:.1f}%",
                   f"{r['false_per_frame']:.2f}", f"{r['proposals_per_frame']:.2f}", f"{r['ms_median']:.2f}"]
                  for r in rows])


def write_csv(path: str | Path, rows: Sequence[dict]) -> None:
    """One line per (variant, set) plus one per size bin; written to a temp name, then renamed."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp")
    keys = ["variant", "set", "frames", "signs", "recalled", "recall", "false_per_frame",
            "proposals_per_frame", "wrong_color", "ms_median"]
    with open(tmp, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(keys + ["size_lo", "size_hi", "found", "total"])
        for r in rows:
            w.writerow([r[k] for k in keys] + ["", "", "", ""])
            for lo, hi, found, total in r["by_size"]:
                w.writerow([r["variant"], r["set"]] + [""] * (len(keys) - 2) + [lo, hi, found, total])
    os.replace(tmp, path)


def plot_recall_by_size(rows: Sequence[dict], size: tuple[int, int] = (640, 400)) -> np.ndarray:
    """uint8 BGR chart: recall (y, 0..1) per sign-size bin (x), one polyline per row."""
    W, H = size
    img = np.full((H, W, 3), 255, np.uint8)
    left, right, top, bottom = 50, W - 150, 20, H - 40
    n_bins = len(SIZE_BINS) - 1
    x_of = lambda b: int(left + (b + 0.5) * (right - left) / n_bins)  # noqa: E731
    y_of = lambda r: int(bottom - r * (bottom - top))  # noqa: E731
    font = cv2.FONT_HERSHEY_SIMPLEX
    for r in np.linspace(0, 1, 6):
        cv2.line(img, (left, y_of(r)), (right, y_of(r)), (220, 220, 220), 1)
        cv2.putText(img, f"{r:.1f}", (8, y_of(r) + 4), font, 0.4, (0, 0, 0), 1, cv2.LINE_AA)
    for b in range(n_bins):
        hi = "+" if b == n_bins - 1 else f"-{SIZE_BINS[b + 1]}"
        cv2.putText(img, f"{SIZE_BINS[b]}{hi}", (x_of(b) - 14, bottom + 16), font, 0.35, (0, 0, 0), 1, cv2.LINE_AA)
    totals = {_size_bin((0, 0, lo, lo)): t for lo, _, _, t in rows[0]["by_size"]} if rows else {}
    for b, t in totals.items():  # how many signs each point stands on (first row's set)
        cv2.putText(img, f"n={t}", (x_of(b) - 14, bottom - 6), font, 0.33, (90, 90, 90), 1, cv2.LINE_AA)
    cv2.putText(img, "sign size min(w,h) px", (left, H - 6), font, 0.4, (0, 0, 0), 1, cv2.LINE_AA)
    cv2.rectangle(img, (left, top), (right, bottom), (0, 0, 0), 1)
    colors = [(200, 60, 0), (0, 0, 200), (0, 150, 0), (0, 140, 255), (150, 0, 150), (100, 100, 100)]
    for k, row in enumerate(rows):
        col = colors[k % len(colors)]
        bins = {int(np.searchsorted(SIZE_BINS, lo)): f / t for lo, _, f, t in row["by_size"] if t}
        pts = [(x_of(b), y_of(r)) for b, r in sorted(bins.items())]
        cv2.polylines(img, [np.array(pts, np.int32)], False, col, 2, cv2.LINE_AA) if len(pts) > 1 else None
        for p in pts:
            cv2.circle(img, p, 3, col, -1, cv2.LINE_AA)
        cv2.putText(img, f"{row['variant']} {row['set']}", (right + 8, top + 16 + 18 * k), font, 0.45, col, 1,
                    cv2.LINE_AA)
    return img


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=500)
    ap.add_argument("--seed", type=int, default=1000)
    ap.add_argument("--width", type=int, default=640)
    ap.add_argument("--height", type=int, default=480)
    ap.add_argument("--min-size", type=int, default=20)
    ap.add_argument("--focus", default="none", help="'signs': frames placed before signs (needs the sampler's focus)")
    ap.add_argument("--out", type=Path, default=None, help="folder for proposals.csv and recall_by_size.png")
    a = ap.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    rows = [r for hard in (False, True)
            for r in eval_many(a.n, a.seed, hard, tuple(VARIANTS), a.min_size, a.width, a.height, True, a.focus)]
    print(format_table(rows))
    if a.out is not None:
        from signlane.draw import write_image

        write_csv(a.out / "proposals.csv", rows)
        write_image(a.out / "recall_by_size.png", plot_recall_by_size(rows))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
