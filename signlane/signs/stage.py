"""The sign stage: colour-mask proposals -> classifier (when a model is present) -> N-of-M confirmation.

One object per stream (the confirmation remembers recent frames, and what the classifier was
sure is no sign: signs/not_signs.py). `step(image)` returns this frame's detections and the
confirmed ones.

With the rows where sign faces stand (a car's camera: `band`), the band is searched whole on one
frame in `search_every` and, on the frames between, only around the frame before's proposals
(proposals.propose_near) that the classifier is not sure are no sign: a sign moves a few pixels
a frame, and one that comes into view is found at the next whole search, at most
search_every - 1 frames late, far ahead of the car. The band's whole-row check (RowBand) frames
are whole searches.
"""
from __future__ import annotations

import time

from signlane.config import SignsConfig
from signlane.signs import proposals
from signlane.signs.classifier import DEFAULT_MODEL, SignClassifier
from signlane.signs.confirm import SignConfirmer
from signlane.signs.face_rows import RowBand
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
        # the rows searched (the drive stack sets them from its camera: signs/face_rows.py);
        # None: every row
        self.band: RowBand | None = None
        self._check: object = None  # a frame whose band check waits for settle()
        # the last frame's proposals but those sure to be no sign: searched around, with a band
        self._tracked: list[SignDetection] = []
        self._since_whole = config.search_every  # frames since the band was last searched whole (the first is)

    def step(self, image_bgr, half=None) -> tuple[tuple[SignDetection, ...], list[SignDetection]]:
        """`half`: the frame at half size (INTER_AREA), if the caller has made it (see propose)."""
        self.settle()  # a check its caller never settled (made before the frame, as it would have been)
        t0 = time.perf_counter()
        band, size = self.band, image_bgr.shape[1::-1]
        rows = band.rows_for(size) if band is not None and self.classifier is not None else None
        if rows is not None and band.due:
            self._check = image_bgr  # (frames are not written to after they are read)
        tracks = rows is not None and self.params.regions and self.params.separate_colors
        if tracks and self._since_whole + 1 < self.config.search_every and self._check is None:
            found = proposals.propose_near(image_bgr, self._tracked, self.params, half)
            self._since_whole += 1
        else:
            found = proposals.propose(image_bgr, self.params, half, rows)
            self._since_whole = 0
        proposed = found
        t1 = time.perf_counter()
        if self.classifier is not None:
            # what the classifier was sure is no sign on the frames just before is not classified again
            found = self.classifier.label_detections(image_bgr, self.not_signs.split(found), self.config.min_score,
                                                     self.not_signs.learn)
        # the next frame searches around this one's proposals, but not around those the
        # classifier is sure are no sign (a crate, a wall: the next whole search finds them again)
        self._tracked = [p for p in proposed if not self.not_signs.holds(p)]
        self.confirmed = self.confirmer.step(found)
        # what this frame's two parts cost (ms), for the driver's timing and the benchmarks
        self.last_ms = {"proposals": (t1 - t0) * 1e3, "classifier": (time.perf_counter() - t1) * 1e3}
        return tuple(found), self.confirmed

    def settle(self) -> None:
        """The band check of the last frame, when it was due (RowBand): every row searched, and
        what the classifier reads among the candidates reaching outside the band counted. A
        driver calls it once the frame's command is out (else the next step makes it first);
        it changes neither that frame's signs nor the confirmation."""
        image, self._check = self._check, None
        if image is None or self.band is None or self.classifier is None:
            return
        outside = [p for p in proposals.propose(image, self.params) if self.band.outside_band(p.box)]
        self.band.check(image.shape[1::-1], self.classifier.label_detections(image, outside, self.config.min_score))

    def reset(self) -> None:
        self._check = None
        self._tracked, self._since_whole = [], self.config.search_every
        self.not_signs.reset()
        self.confirmer.reset()
        self.confirmed = []
