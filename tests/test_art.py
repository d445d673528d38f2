"""Numeric checks of the procedural sign / distractor sprites in signlane.world.art."""

from __future__ import annotations

import numpy as np
import pytest

from signlane.world.art import (
    DISTRACTOR_KINDS,
    SIGN_CLASSES,
    SIGN_NAMES,
    VIA_SIGN_IDS,
    SignStyle,
    draw_distractor,
    draw_sign,
    random_style,
    sign_face_mask,
)

DISCS = ("left", "no_left", "right", "no_right", "straight")
BLUE = ("left", "right", "straight")


def _face_pixels(sprite: np.ndarray) -> np.ndarray:
    return sprite[sign_face_mask(sprite)][:, :3].astype(np.float64)


def test_class_constants() -> None:
    assert SIGN_CLASSES[0] == "unknown"
    assert SIGN_NAMES == SIGN_CLASSES[1:]
    assert set(VIA_SIGN_IDS.values()) == set(SIGN_NAMES)
    assert len(DISTRACTOR_KINDS) == 8


@pytest.mark.parametrize("name", SIGN_NAMES)
@pytest.mark.parametrize("size", [12, 32, 64])
def test_sign_format(name: str, size: int) -> None:
    s = draw_sign(name, size)
    assert s.shape == (size, size, 4) and s.dtype == np.uint8
    assert s[size // 2, size // 2, 3] == 255  # centre is on the face
    assert s[0, 0, 3] < 60  # corner is outside the disc / octagon


@pytest.mark.parametrize("name", DISCS)
def test_disc_coverage(name: str) -> None:
    cov = draw_sign(name, 64)[..., 3].mean() / 255.0
    assert cov == pytest.approx(np.pi / 4, rel=0.05)


def test_octagon_coverage() -> None:
    cov = draw_sign("stop", 64)[..., 3].mean() / 255.0
    assert cov == pytest.approx(2 / (1 + np.sqrt(2)), rel=0.05)  # ~0.83


def test_left_is_mirror_of_right() -> None:
    left, right = draw_sign("left", 64), draw_sign("right", 64)
    assert np.abs(left[:, ::-1].astype(int) - right.astype(int)).mean() < 3
    assert np.abs(left.astype(int) - right.astype(int)).mean() > 10  # but not symmetric


def test_straight_is_symmetric() -> None:
    s = draw_sign("straight", 64).astype(int)
    assert np.abs(s[:, ::-1] - s).mean() < 3


@pytest.mark.parametrize(("name", "side"), [("left", -1), ("right", 1), ("straight", 0),
                                            ("no_left", -1), ("no_right", 1)])
def test_arrow_bends_to_the_named_side(name: str, side: int) -> None:
    s = draw_sign(name, 64).astype(int)
    # Arrow ink: white on blue discs, black on white no_* discs.
    ink = s[..., :3].min(-1) > 200 if name in BLUE else s[..., :3].max(-1) < 80
    ink &= np.hypot(*np.mgrid[-31.5:32, -31.5:32]) < 26  # ignore the rim
    ys, xs = np.nonzero(ink[:30])  # upper half: where the head is
    dx = xs.mean() - 31.5
    if side == 0:
        assert abs(dx) < 1.5
    else:
        # no_* arrows are smaller and partly hidden under the slash, hence a lower bar
        assert np.sign(dx) == side and abs(dx) > (4 if name in BLUE else 1.5)


@pytest.mark.parametrize("name", BLUE)
def test_blue_discs_are_blue(name: str) -> None:
    px = _face_pixels(draw_sign(name, 64))
    assert px[:, 0].mean() > px[:, 2].mean() + 50


@pytest.mark.parametrize("name", ["no_left", "no_right"])
def test_prohibition_ring_and_slash(name: str) -> None:
    s = draw_sign(name, 64).astype(int)
    b, r = s[..., 0], s[..., 2]
    yy, xx = np.mgrid[-31.5:32, -31.5:32]
    rad = np.hypot(yy, xx)
    ring = (rad > 28) & (rad < 30.5)
    assert (r[ring] > b[ring] + 80).mean() > 0.9  # red ring all the way round
    # slash runs top-left to bottom-right: red on that diagonal, not on the other one
    assert r[15, 15] > b[15, 15] + 80 and r[48, 48] > b[48, 48] + 80
    assert not r[15, 48] > b[15, 48] + 80


def test_stop_is_red_with_white_text() -> None:
    px = _face_pixels(draw_sign("stop", 64))
    assert px[:, 2].mean() > px[:, 0].mean() + 60
    bright = (px.min(1) > 180).mean()
    assert 0.05 < bright < 0.40


def test_random_style_strength_zero_is_default() -> None:
    assert random_style(np.random.default_rng(3), strength=0.0) == SignStyle()


def test_random_style_ranges() -> None:
    rng = np.random.default_rng(7)
    for _ in range(50):
        st = random_style(rng)
        assert 0.10 <= st.ring_frac <= 0.22 and 0.10 <= st.arrow_width_frac <= 0.22
        assert 0.0 <= st.border_frac <= 0.08 and 0.0 <= st.fade <= 0.5
        assert all(0 <= c <= 255 and isinstance(c, int) for c in st.blue + st.red + st.white)
        px = _face_pixels(draw_sign("left", 32, st, rng))
        assert px[:, 0].mean() > px[:, 2].mean()  # still blue-ish after randomisation


def test_deterministic_with_seed() -> None:
    def make(seed: int) -> list[np.ndarray]:
        rng = np.random.default_rng(seed)
        out = [draw_sign(n, 48, random_style(rng), rng) for n in SIGN_NAMES]
        return out + [draw_distractor(k, 40, rng) for k in DISTRACTOR_KINDS]

    a, b, c = make(11), make(11), make(12)
    assert all(np.array_equal(x, y) for x, y in zip(a, b))
    assert not all(np.array_equal(x, y) for x, y in zip(a, c))


def test_jitter_changes_geometry() -> None:
    st = SignStyle(stroke_jitter=1.0)
    a = draw_sign("right", 64, st, np.random.default_rng(1))
    b = draw_sign("right", 64, st, np.random.default_rng(2))
    assert np.abs(a.astype(int) - b.astype(int)).mean() > 0.5


def test_unknown_names_raise() -> None:
    with pytest.raises(ValueError, match="yield"):
        draw_sign("yield", 32)
    with pytest.raises(ValueError, match="tree"):
        draw_distractor("tree", 32, np.random.default_rng(0))


@pytest.mark.parametrize("kind", DISTRACTOR_KINDS)
def test_distractor_format(kind: str) -> None:
    rng = np.random.default_rng(0)
    for size in (12, 32, 80):
        for _ in range(4):
            d = draw_distractor(kind, size, rng)
            assert d.ndim == 3 and d.shape[0] == size and d.shape[2] == 4
            assert d.dtype == np.uint8 and d.shape[1] >= 1
            assert d[..., 3].max() == 255 and d[..., 3].mean() > 0.2 * 255


def test_billboard_is_wide_and_cone_has_transparent_corners() -> None:
    rng = np.random.default_rng(5)
    assert draw_distractor("billboard", 40, rng).shape[1] > 40
    cone = draw_distractor("cone", 64, rng)
    assert cone[0, 0, 3] == 0 and cone[0, -1, 3] == 0


def test_stop_word_is_what_is_written() -> None:
    def white(word: str) -> float:
        return float((_face_pixels(draw_sign("stop", 64, SignStyle(stop_word=word))).min(1) > 180).mean())

    blank, stop, alto = white(""), white("STOP"), white("ALTO")
    assert blank < 0.12 < stop  # only the white rim is left on a blank octagon
    assert abs(alto - stop) < 0.1 and not np.array_equal(draw_sign("stop", 64), draw_sign("stop", 64, SignStyle(stop_word="ALTO")))


def test_no_entry_is_a_red_disc_with_a_white_bar() -> None:
    d = draw_distractor("no_entry", 64, np.random.default_rng(0)).astype(int)
    b, r = d[..., 0], d[..., 2]
    assert d[0, 0, 3] < 60 and d[32, 32, 3] == 255  # a disc: corners outside
    assert min(d[32, 32, :3]) > 200 and min(d[32, 16, :3]) > 200  # the bar runs across the middle
    assert r[10, 32] > b[10, 32] + 80 and r[54, 32] > b[54, 32] + 80  # red above and below it
