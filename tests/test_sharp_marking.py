"""The segmentation model's marking mask at a large frame's size is drawn as sharp as the frame's
own paint (lanes/sharp_marking.py): a band several pixels wider than the line keeps the line's
pixels and loses its margins; a band over ground that shows no line, and every band at a frame
whose output cells are within the tolerance (3 px), stay as the model drew them."""
import cv2
import numpy as np

from signlane.eval_masks import MaskCounts
from signlane.lanes.sharp_marking import SharpParams, sharpen_marking


def _road(h=480, w=640, line_px=4, step=60):
    """A grey road with a slanted white line `line_px` wide, `step` lightness levels above it,
    and its true mask."""
    img = np.full((h, w, 3), 90, np.uint8)
    true = np.zeros((h, w), np.uint8)
    cv2.line(true, (200, h - 1), (330, h // 2), 255, line_px)
    img[true > 0] = 90 + step
    return img, true


def _band(true, px):
    """The model's band: the line dilated by `px` pixels either side (a 160-wide map brought up)."""
    return cv2.dilate(true, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * px + 1, 2 * px + 1)))


def test_a_wide_band_is_sharpened_to_the_line():
    img, true = _road()
    band = _band(true, 6)
    sharp = sharpen_marking(band, img, map_size=(160, 120))
    before, after = MaskCounts(), MaskCounts()
    before.add(band, true)
    after.add(sharp, true)
    b, a = before.summary(), after.summary()
    assert b["precision"] < 0.6 and a["precision"] > 0.95  # the margins were counted as paint
    assert a["recall"] > 0.99  # every painted pixel still has a predicted one within 2 px
    assert np.count_nonzero(sharp & ~band) == 0  # it only takes pixels away
    # at cells of 2 px (a 320x240 map brought up to 640x480) the band is left alone
    assert np.array_equal(sharpen_marking(band, img, map_size=(320, 240)), band)


def test_a_band_where_the_frame_shows_no_line_is_kept():
    img, true = _road(step=3)  # 3 lightness levels: fog, night
    band = _band(true, 6)
    assert np.array_equal(sharpen_marking(band, img, map_size=(160, 120)), band)
    # with a lower bar the faint line is sharpened too
    sharp = sharpen_marking(band, img, map_size=(160, 120), p=SharpParams(min_contrast=1.0))
    assert np.count_nonzero(sharp) < 0.5 * np.count_nonzero(band)


def test_a_line_lighter_than_its_neighbourhood_only_on_one_side_of_the_band_keeps_its_core():
    # a bright verge beside the road inside the window: the line's step is measured on its own
    # local ground (the top-hat), so the band still shrinks to the line
    img, true = _road()
    img[:, 420:] = 200
    sharp = sharpen_marking(_band(true, 6), img, map_size=(160, 120))
    counts = MaskCounts()
    counts.add(sharp, true)
    assert counts.summary()["precision"] > 0.95 and counts.summary()["recall"] > 0.99
