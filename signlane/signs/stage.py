"""The sign stage: colour-mask proposals -> classifier (when a model is present) -> N-of-M confirmation.

One object per stream (the confirmation remembers recent frames, and what the classifier was
sure is no sign: signs/not_signs.py). `step(image)` returns this frame's detections and the
confirmed ones.
"""
from __future__ import annotations

import time
from dataclasses import replace

from signlane.config import SignsConfig
from signlane.signs import proposals
from signlane.signs.classifier import DEFAULT_MODEL, SignClassifier, crop
from signlane.signs.confirm import SignConfirmer
from signlane.signs.not_signs import NotSigns
from signlane.types import SignDetection


class SignStage:
    def __init__(self, config: SignsConfig):
        self.config = config
        self.params = (proposals.ProposalParams.published() if config.variant == "published"
                       else proposals.ProposalParams())
        path = config.model or DEFAULT_MODEL
        # a named model must load; the shipped one may be absent (then proposals only)
        self.classifier = SignClassifier(path) if (config.model or DEFAULT_MODEL.exists()) else None
        self.confirmer = SignConfirmer(config.confirm_n, config.confirm_m)
        self.not_signs = NotSigns()
        self.confirmed: list[SignDetection] = []
        self.last_ms: dict[str, float] = {}

    def step(self, image_bgr, half=None) -> tuple[tuple[SignDetection, ...], list[SignDetection]]:
        """`half`: the frame at half size (INTER_AREA), if the caller has made it (see propose)."""
        t0 = time.perf_counter()
        found = proposals.propose(image_bgr, self.params, half)
        t1 = time.perf_counter()
        if self.classifier is not None:
            found = self._classify(image_bgr, found)
        self.confirmed = self.confirmer.step(found)
        # what this frame's two parts cost (ms), for the driver's timing and the benchmarks
        self.last_ms = {"proposals": (t1 - t0) * 1e3, "classifier": (time.perf_counter() - t1) * 1e3}
        return tuple(found), self.confirmed

    def _classify(self, image_bgr, found: list[SignDetection]) -> list[SignDetection]:
        """Proposals relabelled by the classifier ('unknown' and low-score ones dropped), but for
        those it was sure of as no sign on the frames just before (not classified again)."""
        fresh, _ = self.not_signs.split(found)
        if not fresh:
            return []
        results = self.classifier.classify([crop(image_bgr, p.box) for p in fresh])
        out = []
        for p, (label, score, _) in zip(fresh, results):
            self.not_signs.learn(p, label, score)
            if label != "unknown" and score >= self.config.min_score:
                out.append(replace(p, label=label, score=score))
        return out

    def reset(self) -> None:
        self.not_signs.reset()
        self.confirmer.reset()
        self.confirmed = []
