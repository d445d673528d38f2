"""What the classifier was sure is no sign (a blue wall proposed on every frame) is not classified
again on the next frames, but re-checked every third; a proposal that moved, a sign, a doubtful
verdict and a new stream are classified as before."""
from __future__ import annotations

import numpy as np
import pytest

from signlane.config import SignsConfig
from signlane.signs.classifier import SignClassifier
from signlane.signs.not_signs import NotSigns
from signlane.signs.stage import SignStage
from signlane.types import SignDetection


def _prop(x: int, color: str = "blue") -> SignDetection:
    return SignDetection("unknown", 0.8, (x, 100, 40, 40), color)


class FakeClassifier:
    """Red proposals are stop signs; blue ones are no sign, sure or not (`unsure`). The stage
    reaches it through the real classifier's label_detections."""

    label_detections = SignClassifier.label_detections

    def __init__(self, unsure: bool = False):
        self.seen: list[int] = []  # the x of each crop classified
        self.unsure = unsure

    def classify(self, crops):
        out = []
        for c in crops:
            self.seen.append(int(c[0, 0, 0]))
            red = int(c[0, 0, 2]) > 100
            out.append(("stop", 0.99, {}) if red else ("unknown", 0.6 if self.unsure else 0.99, {}))
        return out


def _frame(xs_colors) -> np.ndarray:
    """A frame whose proposals' crops carry their x in the blue channel (and red for red ones)."""
    img = np.zeros((480, 640, 3), np.uint8)
    for x, color in xs_colors:
        img[100:140, x:x + 40, 0] = x
        if color == "red":
            img[100:140, x:x + 40, 2] = 200
    return img


@pytest.fixture
def stage(monkeypatch):
    s = SignStage(SignsConfig())
    s.classifier = FakeClassifier()
    return s


def _run(stage, frames, monkeypatch):
    """Steps the stage over (proposals per frame); returns the labels found per frame."""
    from signlane.signs import proposals as prop_module
    out = []
    for props in frames:
        monkeypatch.setattr(prop_module, "propose", lambda img, params, half=None, rows=None, p=props: list(p))
        found, _ = stage.step(_frame([(p.box[0], p.color) for p in props]))
        out.append([d.label for d in found])
    return out


def test_a_wall_is_classified_on_every_third_frame_a_sign_on_every_frame(stage, monkeypatch):
    frames = [[_prop(20 + i), _prop(120 + i, "red")] for i in range(7)]  # both creep 1 px a frame
    labels = _run(stage, frames, monkeypatch)
    assert labels == [["stop"]] * 7
    walls = [x for x in stage.classifier.seen if x < 100]
    assert walls == [20, 23, 26]  # frames 0, 3 and 6
    assert [x for x in stage.classifier.seen if x >= 100] == list(range(120, 127))


def test_a_proposal_that_moved_or_a_doubtful_verdict_is_classified_again(stage, monkeypatch):
    _run(stage, [[_prop(200)], [_prop(230)]], monkeypatch)  # 30 px of 40: IoU 0.14, another thing
    assert stage.classifier.seen == [200, 230]
    stage.reset()
    stage.classifier = FakeClassifier(unsure=True)
    _run(stage, [[_prop(200)], [_prop(200)], [_prop(200)]], monkeypatch)
    assert stage.classifier.seen == [200, 200, 200]  # 0.6 "unknown" is not sure enough to remember


def test_a_new_stream_forgets(stage, monkeypatch):
    _run(stage, [[_prop(200)]], monkeypatch)
    stage.reset()
    _run(stage, [[_prop(200)]], monkeypatch)
    assert stage.classifier.seen == [200, 200]


def test_colour_counts_and_the_recheck_must_be_a_frame_or_more():
    ns = NotSigns()
    ns.learn(_prop(200), "unknown", 0.99)
    assert ns.split([_prop(200, "red")]) == [_prop(200, "red")]  # a red thing where a blue one was is not the blue one
    ns.learn(_prop(200), "unknown", 0.99)
    assert ns.split([_prop(202)]) == []  # the blue one, 2 px on
    with pytest.raises(ValueError, match="recheck"):
        NotSigns(recheck=0)
