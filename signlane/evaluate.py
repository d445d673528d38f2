"""`signlane eval`: seeded synthetic test sets and the lane-method scores on them.

Test sets: 'normal' = randomised roads, looks and cameras with the normal effects; 'hard' =
the hard effects (glare, blur, noise, JPEG, pose jitter) with twice the worn/faded paint and
shadows. Each method is given the nominal camera (what a user calibrates), not the per-frame
jittered one.
"""
from __future__ import annotations

import csv
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from tqdm import tqdm

from signlane import lanes
from signlane.world.sampling import FrameSampler, SamplerConfig

CURVED_K = 0.01  # |curvature| above which the bend's direction is scored (radius < 100 m)


def test_set_config(hard: bool, width: int = 320, height: int = 240) -> SamplerConfig:
    if hard:
        return SamplerConfig(width=width, height=height, effects="hard", randomise=True, looks_strength=2.0)
    return SamplerConfig(width=width, height=height, effects="normal", randomise=True)


@dataclass
class LaneScores:
    method: str
    n: int = 0
    found: int = 0
    offset_err: dict[int, float] = field(default_factory=dict)  # by frame index, found frames only
    heading_err_deg: list[float] = field(default_factory=list)
    curve_total: int = 0
    curve_agree: int = 0
    ms: list[float] = field(default_factory=list)

    def add(self, est, truth, ms: float, index: int | None = None) -> None:
        self.n += 1
        self.ms.append(ms)
        if not est.found:
            return
        self.found += 1
        self.offset_err[self.n - 1 if index is None else index] = abs(est.offset - truth.offset)
        self.heading_err_deg.append(abs(math.degrees(est.heading - truth.heading)))
        if abs(truth.curvature) > CURVED_K:
            self.curve_total += 1
            self.curve_agree += int(np.sign(est.curvature) == np.sign(truth.curvature))

    def summary(self) -> dict:
        def pct(a, q):
            return float(np.percentile(a, q)) if a else float("nan")
        return {"method": self.method, "n": self.n, "found_pct": 100.0 * self.found / max(self.n, 1),
                "offset_err_median": pct(list(self.offset_err.values()), 50),
                "offset_err_p95": pct(list(self.offset_err.values()), 95),
                "heading_err_median_deg": pct(self.heading_err_deg, 50),
                "curvature_sign_pct": 100.0 * self.curve_agree / max(self.curve_total, 1),
                "ms_per_frame": float(np.median(self.ms)) if self.ms else float("nan")}


def eval_lanes(method: str, n: int = 500, seed: int = 1000, hard: bool = False, variant: str = "robust",
               width: int = 320, height: int = 240, progress: bool = True, overrides: dict | None = None,
               errors: dict[int, float] | None = None) -> dict:
    """Score one lane method on a seeded test set; frames are independent (state reset each).
    `overrides` set method parameters (e.g. {"model": "lanes.onnx"} for segnet); `errors`, when
    given, receives each found frame's offset error by frame index (for `add_common_errors`)."""
    sampler = FrameSampler(seed, test_set_config(hard, width, height))
    scores = LaneScores(method if variant == "robust" else f"{method}:{variant}")
    it = range(n)
    for i in tqdm(it, desc=f"eval {scores.method}", unit="frame", disable=not progress):
        smp = sampler.sample(i)
        m = lanes.get(method, camera=smp.truth.nominal_camera, variant=variant, **(overrides or {}))
        t0 = time.perf_counter()
        est = m(smp.image)
        scores.add(est, smp.truth, (time.perf_counter() - t0) * 1e3, i)
    if errors is not None:
        errors.update(scores.offset_err)
    return scores.summary()


def add_common_errors(rows: list[dict], errors: list[dict[int, float]]) -> None:
    """Give each row (eval_lanes' summaries, with each one's per-frame `errors`) the median
    offset error over the frames that every row's method found, and their count. A method that
    finds more frames finds harder ones: its median over all it found is not comparable with one
    that gives up on them; over the shared frames it is."""
    common = set.intersection(*(set(e) for e in errors)) if errors else set()
    for row, err in zip(rows, errors):
        row["offset_err_median_common"] = float(np.median([err[i] for i in common])) if common else float("nan")
        row["common_frames"] = len(common)


COLUMNS = [("method", "method", "{}"), ("found_pct", "found %", "{:.1f}"),
           ("offset_err_median", "off med", "{:.3f}"), ("offset_err_p95", "off p95", "{:.3f}"),
           ("offset_err_median_common", "off med shared", "{:.3f}"),
           ("heading_err_median_deg", "head med deg", "{:.2f}"), ("curvature_sign_pct", "curv sign %", "{:.1f}"),
           ("ms_per_frame", "ms/frame", "{:.2f}")]


def format_table(rows: list[dict]) -> str:
    from signlane.tables import table
    return table([h for _, h, _ in COLUMNS], [[f.format(r[k]) for k, _, f in COLUMNS] for r in rows])


def write_csv(path: str | Path, rows: list[dict]) -> None:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp")
    with tmp.open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    tmp.replace(path)


def plot_lanes(path: str | Path, rows: list[dict]) -> None:
    """Two bar charts stacked: lane found % and offset errors (median, p95) per method."""
    from signlane.draw import write_image
    from signlane.plots import bar_chart
    labels = [r["method"] for r in rows]
    found = bar_chart("lane found %", labels, {"found %": [r["found_pct"] for r in rows]}, ymax=100.0)
    errs = bar_chart("lateral offset error (fraction of lane width)", labels,
                     {"median": [r["offset_err_median"] for r in rows], "p95": [r["offset_err_p95"] for r in rows]})
    write_image(path, np.vstack([found, errs]))


def eval_signs(data: str | Path, model: str | Path | None = None, min_score: float = 0.5,
               out: str | Path | None = None) -> dict:
    """Classifier scores on an ImageFolder crop set (e.g. a fresh `signlane gen signs` seed):
    accuracy, recall per class, and how often a non-sign is accepted as a sign (argmax not
    'unknown' and score >= min_score, as the runtime would act on it). With `out`, the set's
    confusion.png and errors_<class>.png/.txt (signlane/sign_report.py) are written there."""
    import cv2
    from signlane.media import IMAGE_EXT
    from signlane.signs.classifier import DEFAULT_MODEL, SignClassifier
    clf = SignClassifier(model or DEFAULT_MODEL, threads=2, batch=256)
    root = Path(data)
    crops, labels, files = [], [], []
    for d in sorted(p for p in root.iterdir() if p.is_dir() and p.name in clf.classes):
        for f in sorted(d.iterdir()):
            if f.suffix.lower() in IMAGE_EXT:
                crops.append(cv2.imread(str(f)))
                labels.append(clf.classes.index(d.name))
                files.append(f)
    if not crops:
        raise ValueError(f"{root}: no crops in class folders ({', '.join(clf.classes)})")
    probs = clf.probabilities(crops)
    pred, y = probs.argmax(axis=1), np.array(labels)
    unknown = clf.classes.index("unknown")
    neg = y == unknown
    accepted = (pred != unknown) & (probs.max(axis=1) >= min_score)
    recall = {c: float((pred[y == k] == k).mean()) for k, c in enumerate(clf.classes) if (y == k).any()}
    if out is not None:
        from signlane.sign_report import write_sign_report
        write_sign_report(out, files, y, pred, probs.max(axis=1), clf.classes, root.name)
    return {"model": str(model or DEFAULT_MODEL), "n": int(len(y)), "accuracy": float((pred == y).mean()),
            "min_recall": min(recall.values()), "recall": recall,
            "non_sign_accepted": float(accepted[neg].mean()) if neg.any() else float("nan")}
