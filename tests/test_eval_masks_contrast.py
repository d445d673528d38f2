"""`eval masks`'s recall by paint contrast: paint the image shows, and paint it hides."""
import numpy as np

from signlane.eval_masks import ContrastRecall, MaskCounts


def _frame() -> tuple[np.ndarray, np.ndarray]:
    """A grey road (100) with a bright line (200) down column 10 and one hidden in it (102) down
    column 30, both labelled paint; row 0 unlabelled."""
    img = np.full((40, 48, 3), 100, np.uint8)
    img[:, 10] = 200
    img[:, 30] = 102
    ids = np.zeros((40, 48), np.uint8)
    ids[:, 10] = ids[:, 30] = 1
    ids[0] = 255
    return img, ids


def test_hidden_paint_and_seen_paint_fall_in_their_own_contrast_bins():
    img, ids = _frame()
    pred = np.zeros_like(ids)
    pred[:, 11] = 255  # the bright line drawn a pixel off, the hidden one missed
    counts, contrast = MaskCounts(), ContrastRecall()
    found = counts.add(pred, ids == 1, 2, ids == 255)
    assert found[1:, 10].all() and not found[:, 30].any() and not found[0].any()
    contrast.add(img, ids, found)
    rows = {r["contrast"]: r for r in contrast.rows()}
    assert rows["0-4"]["paint_share"] == rows["64-256"]["paint_share"] == 0.5
    assert rows["0-4"]["recall"] == 0.0 and rows["64-256"]["recall"] == 1.0
    assert rows["0-4"]["missed_share"] == 1.0  # every pixel missed is one the image hides
    assert sum(r["paint_share"] for r in rows.values()) == 1.0
    assert counts.summary()["recall"] == 0.5  # the same pixels as the plain recall
