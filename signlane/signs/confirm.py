"""Temporal confirmation of signs: a label counts once it is seen in N of the last M frames.

One frame's false positive (a red billboard classified as stop once) must not make the car stop;
a real sign is seen in many consecutive frames as the car approaches it.
"""
from __future__ import annotations

from collections import deque

from signlane.types import SignDetection


class SignConfirmer:
    """N-of-M filter per label. `step(detections)` -> the confirmed detections of this frame
    (the newest box of each confirmed label; a confirmed label not seen this frame is held with
    its last box until it drops below N of M)."""

    def __init__(self, n: int = 3, m: int = 5):
        if not 1 <= n <= m:
            raise ValueError(f"need 1 <= n <= m, got n={n}, m={m}")
        self.n, self.m = n, m
        self.history: deque[dict[str, SignDetection]] = deque(maxlen=m)
        self.last: dict[str, SignDetection] = {}

    def step(self, detections: list[SignDetection] | tuple[SignDetection, ...]) -> list[SignDetection]:
        best: dict[str, SignDetection] = {}
        for d in detections:
            if d.label not in best or d.score > best[d.label].score:
                best[d.label] = d
        self.history.append(best)
        self.last.update(best)
        counts: dict[str, int] = {}
        for frame in self.history:
            for label in frame:
                counts[label] = counts.get(label, 0) + 1
        return [self.last[label] for label, c in sorted(counts.items()) if c >= self.n]

    def reset(self) -> None:
        self.history.clear()
        self.last.clear()

    def close(self) -> None:
        self.reset()
