"""Proposals the classifier was sure are no sign, remembered from frame to frame.

A blue wall or a red car beside the road is proposed on every frame it is in view, and the
classifier said "unknown" about it last frame too: at 30 frames/s the same thing stands in
nearly the same box. Such a proposal is not classified again for a few frames; it is re-checked
every `recheck` frames (a sign far away that the classifier could not yet read grows, moves and
is read again within a tenth of a second), and only verdicts of at least `sure` are remembered.
"""
from __future__ import annotations

from dataclasses import dataclass

from signlane.signs.proposals import box_iou
from signlane.types import SignDetection

SAME_IOU = 0.7  # a proposal this close to a remembered one's box (same colour) is the same thing


@dataclass
class _Seen:
    box: tuple[int, int, int, int]
    color: str
    age: int  # frames since the classifier last looked at it


class NotSigns:
    def __init__(self, recheck: int = 3, sure: float = 0.95):
        if recheck < 1:
            raise ValueError(f"recheck must be >= 1 frame, got {recheck}")
        self.recheck, self.sure = recheck, sure
        self._seen: list[_Seen] = []

    def split(self, proposals: list[SignDetection]) -> list[SignDetection]:
        """This frame's proposals to classify: all but those known to be no sign. The remembered
        ones not seen again are forgotten, the ones seen again grow a frame older."""
        fresh, kept = [], []
        for p in proposals:
            match = next((s for s in self._seen if s.color == p.color and s.age + 1 < self.recheck
                          and box_iou(s.box, p.box) >= SAME_IOU), None)
            if match is None:
                fresh.append(p)
            else:
                self._seen.remove(match)
                kept.append(_Seen(p.box, p.color, match.age + 1))
        self._seen = kept
        return fresh

    def learn(self, proposal: SignDetection, label: str, score: float) -> None:
        """The classifier's verdict on a proposal it has just looked at."""
        if label == "unknown" and score >= self.sure:
            self._seen.append(_Seen(proposal.box, proposal.color, 0))

    def holds(self, proposal: SignDetection) -> bool:
        """Is this proposal (of the frame just split and learned from) one remembered as no sign?"""
        return any(s.box == proposal.box and s.color == proposal.color for s in self._seen)

    def reset(self) -> None:
        self._seen = []
