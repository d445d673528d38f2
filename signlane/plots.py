"""Charts people read: grouped bar charts and confusion matrices, drawn with matplotlib (its
headless Agg backend) and returned as BGR uint8 images, so they are written like every other
picture (`signlane.draw.write_image`). Overlays on camera frames stay in cv2 (signlane/draw.py).
matplotlib is imported on first use: commands that draw no chart never load it."""
from __future__ import annotations

from typing import Sequence

import numpy as np


def _pyplot():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _to_bgr(fig) -> np.ndarray:
    fig.canvas.draw()
    rgba = np.asarray(fig.canvas.buffer_rgba())
    img = np.ascontiguousarray(rgba[:, :, 2::-1])  # RGBA -> BGR
    _pyplot().close(fig)
    return img


def bar_chart(title: str, labels: Sequence[str], series: dict[str, Sequence[float]], ymax: float | None = None,
              ylabel: str = "") -> np.ndarray:
    """One group of bars per label (full names, turned when they are long), one bar per series,
    each bar with its value."""
    plt = _pyplot()
    n, k = len(labels), max(1, len(series))
    fig, ax = plt.subplots(figsize=(max(6.0, 1.3 * n + 2.0), 4.2), dpi=100)  # one width per label count: charts stack
    width = 0.8 / k
    x = np.arange(n)
    for i, (name, values) in enumerate(series.items()):
        vals = np.asarray(values, float)
        bars = ax.bar(x + (i - (k - 1) / 2) * width, np.nan_to_num(vals), width, label=name)
        ax.bar_label(bars, labels=[f"{v:.3g}" if np.isfinite(v) else "n/a" for v in vals], fontsize=7, padding=2)
    long = max((len(s) for s in labels), default=0) > 10  # turned, so that full names fit
    ax.set_xticks(x, labels, rotation=30 if long else 0, ha="right" if long else "center", fontsize=8)
    ax.set_title(title)
    ax.set_ylabel(ylabel)
    if ymax is not None:
        ax.set_ylim(0, ymax * 1.08)
    ax.grid(axis="y", alpha=0.3)
    if len(series) > 1:
        ax.legend(fontsize=8)
    fig.tight_layout()
    return _to_bgr(fig)


def confusion_matrix(conf: Sequence[Sequence[int]], classes: Sequence[str], title: str) -> np.ndarray:
    """Rows = true class, columns = predicted; colour is the row's share, every non-zero cell
    shows its count (a single error is the one worth seeing), full class names."""
    plt = _pyplot()
    m = np.asarray(conf, np.int64)
    share = m / np.maximum(m.sum(axis=1, keepdims=True), 1)
    n = len(classes)
    fig, ax = plt.subplots(figsize=(1.0 * n + 2.5, 0.85 * n + 2.0), dpi=100)
    im = ax.imshow(share, cmap="Blues", vmin=0.0, vmax=1.0)
    for i in range(n):
        for j in range(n):
            if m[i, j]:
                colour = "white" if share[i, j] > 0.5 else ("crimson" if i != j else "black")
                ax.text(j, i, str(m[i, j]), ha="center", va="center", fontsize=8, color=colour,
                        fontweight="bold" if i != j else "normal")
    ax.set_xticks(range(n), classes, rotation=35, ha="right", fontsize=8)
    ax.set_yticks(range(n), [f"{c} ({m[i].sum()})" for i, c in enumerate(classes)], fontsize=8)
    ax.set_xlabel("predicted")
    ax.set_ylabel("true class (crops)")
    ax.set_title(title, fontsize=9)
    fig.colorbar(im, ax=ax, fraction=0.046, pad=0.04, label="share of the true class")
    fig.tight_layout()
    return _to_bgr(fig)


def steering_chart(teacher: Sequence[float], predicted: dict[str, Sequence[float]], xlabel: str = "frame",
                   title: str = "steering: predicted vs teacher") -> np.ndarray:
    """Steering over time: the teacher's as a thick grey line, each model's over it."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(10.0, 3.6), dpi=100)
    ax.plot(np.asarray(teacher, float), color="0.55", linewidth=2.4, label="teacher")
    for name, values in predicted.items():
        ax.plot(np.asarray(values, float), linewidth=1.0, label=name)
    ax.set_ylim(-1.05, 1.05)
    ax.axhline(0.0, color="0.8", linewidth=0.6)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("steering (+ right)")
    ax.set_title(title)
    ax.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    return _to_bgr(fig)
