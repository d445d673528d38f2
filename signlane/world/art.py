"""Procedural traffic-sign and distractor sprites (numpy + OpenCV only, no image assets).

Every sprite is a ``uint8`` array of shape ``(h, w, 4)`` with channels **B, G, R, A**
(OpenCV colour order plus straight, non-premultiplied alpha). Alpha is 255 on the object,
0 outside, with an antialiased edge. Colour outside the object is the object's outermost
colour (not black), so alpha blending / perspective warps show no dark fringe.

Everything is drawn on a 4x supersampled canvas and box-filtered down (``INTER_AREA``)
so that 12-16 px sprites still have correct coverage and smooth edges. Drawing is
deterministic: identical arguments (and identically seeded ``rng``) give identical pixels.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import lru_cache

import cv2
import numpy as np

SIGN_CLASSES = ("unknown", "left", "no_left", "right", "no_right", "straight", "stop")
SIGN_NAMES = SIGN_CLASSES[1:]
VIA_SIGN_IDS = {0: "left", 1: "no_left", 2: "right", 3: "no_right", 4: "stop", 5: "straight"}
DISTRACTOR_KINDS = (
    "red_disc", "blue_disc", "blue_rect", "no_entry",
    "billboard", "warning_triangle", "cone", "box",
)

BGR = tuple[int, int, int]
_SS = 4  # supersampling factor
_SHIFT = 4  # fractional bits for sub-pixel vertex positions in cv2 drawing calls
_FONTS = (cv2.FONT_HERSHEY_SIMPLEX, cv2.FONT_HERSHEY_DUPLEX,
          cv2.FONT_HERSHEY_COMPLEX, cv2.FONT_HERSHEY_TRIPLEX)
_FADE_TO = (205, 208, 210)  # sun-bleached paint drifts toward this grey-white (BGR)
_N_JIT = 8  # number of jitter draws; fixed so rng consumption never depends on the sign


@dataclass(frozen=True)
class SignStyle:
    """Appearance parameters for one sprite. Colours are BGR ``uint8`` triples."""

    blue: BGR = (160, 80, 0)  # blue disc
    red: BGR = (30, 30, 200)  # ring, slash, octagon
    white: BGR = (245, 245, 245)
    black: BGR = (20, 20, 20)
    ring_frac: float = 0.16  # red ring thickness / radius
    arrow_width_frac: float = 0.16  # arrow stroke width / sprite size
    border_frac: float = 0.05  # white rim around blue discs / octagon, / radius
    fade: float = 0.0  # 0..1 blend of all paint toward grey-white
    stroke_jitter: float = 0.0  # 0..1 random geometry variation of arrow / text
    font: int = cv2.FONT_HERSHEY_SIMPLEX
    stop_word: str = "STOP"  # a red octagon means stop in any language (ALTO, PARE, ARRET...)


def _hsv_jitter(bgr: BGR, rng: np.random.Generator, s: float,
                dh: float, ds: float, dv: float) -> BGR:
    h, sat, v = cv2.cvtColor(np.uint8([[bgr]]), cv2.COLOR_BGR2HSV)[0, 0].astype(np.float64)
    h = (h + s * rng.uniform(-dh, dh)) % 180  # OpenCV hue range is 0..180
    sat = np.clip(sat * (1 + s * rng.uniform(-ds, 0.3 * ds)), 40, 255)
    v = np.clip(v * (1 + s * rng.uniform(-dv, dv)), 40, 255)
    hsv = np.uint8([[[int(round(h)) % 180, int(round(sat)), int(round(v))]]])
    return tuple(int(c) for c in cv2.cvtColor(hsv, cv2.COLOR_HSV2BGR)[0, 0])


def random_style(rng: np.random.Generator, strength: float = 1.0) -> SignStyle:
    """Random appearance; ``strength`` in [0, 1] scales every deviation (0 -> default)."""
    s = float(np.clip(strength, 0.0, 1.0))
    d = SignStyle()
    if s == 0.0:
        return d  # exact default, avoids HSV round-trip rounding

    def mix(default: float, lo: float, hi: float) -> float:
        return float(default + s * (rng.uniform(lo, hi) - default))

    blue = _hsv_jitter(d.blue, rng, s, 10, 0.25, 0.35)
    red = _hsv_jitter(d.red, rng, s, 7, 0.25, 0.3)
    dim, tint = rng.uniform(0, 45), rng.uniform(-8, 8, 3)
    white = tuple(int(np.clip(245 - s * dim + s * t, 0, 255)) for t in tint)
    black = (int(20 + s * rng.uniform(0, 45)),) * 3
    font = _FONTS[int(rng.integers(len(_FONTS)))] if rng.random() < s else d.font
    return SignStyle(
        blue=blue, red=red, white=white, black=black,
        ring_frac=mix(d.ring_frac, 0.10, 0.22),
        arrow_width_frac=mix(d.arrow_width_frac, 0.10, 0.22),
        border_frac=mix(d.border_frac, 0.0, 0.08),
        fade=s * rng.uniform(0, 0.5), stroke_jitter=s * rng.uniform(0, 0.6), font=font,
    )


def _faded(st: SignStyle) -> SignStyle:
    if st.fade <= 0:
        return st
    f = float(np.clip(st.fade, 0, 1))

    def mixc(c: BGR) -> BGR:
        return tuple(int(round(a * (1 - f) + b * f)) for a, b in zip(c, _FADE_TO))

    return replace(st, blue=mixc(st.blue), red=mixc(st.red),
                   white=mixc(st.white), black=mixc(st.black))


@lru_cache(maxsize=256)
def _glyph_mask(text: str, font: int) -> np.ndarray:
    """Tight float32 coverage mask of bold text; stretched into a box by the caller."""
    scale, th = 3.0, 10
    (tw, tht), base = cv2.getTextSize(text, font, scale, th)
    pad = 2 * th
    img = np.zeros((tht + base + 2 * pad, tw + 2 * pad), np.uint8)
    cv2.putText(img, text, (pad, pad + tht), font, scale, 255, th, cv2.LINE_AA)
    ys, xs = np.nonzero(img)
    m = img[ys.min():ys.max() + 1, xs.min():xs.max() + 1].astype(np.float32) / 255.0
    m.flags.writeable = False
    return m


def _fp(pts: np.ndarray) -> np.ndarray:
    return np.round(np.asarray(pts, np.float64) * (1 << _SHIFT)).astype(np.int32)


class _Pad:
    """4x supersampled BGRA canvas addressed in unit coords: x, y in [-1, 1], y down.

    The unit square maps onto the whole sprite, so on non-square pads x and y units
    differ; circles and stroke widths use the shorter half-side as their unit.
    """

    def __init__(self, h: int, w: int, outer: BGR) -> None:
        self.h, self.w = h, w
        # Edge colour under alpha 0 avoids dark fringes later. Filled as packed uint32
        # because numpy broadcasting a 4-tuple over the last axis is ~10x slower.
        px = np.frombuffer(bytes((*outer, 0)), np.uint32)[0]
        H, W = h * _SS, w * _SS
        self.img = np.full((H, W), px, np.uint32).view(np.uint8).reshape(H, W, 4)
        self.c = np.array([(W - 1) / 2, (H - 1) / 2])
        self.k = np.array([W / 2, H / 2])
        self.r = float(self.k.min())

    def px(self, pts) -> np.ndarray:
        return self.c + np.asarray(pts, np.float64).reshape(-1, 2) * self.k

    def poly(self, pts, color: BGR) -> None:
        cv2.fillPoly(self.img, [_fp(self.px(pts))], (*color, 255), cv2.LINE_AA, _SHIFT)

    def rect(self, x0: float, y0: float, x1: float, y1: float, color: BGR) -> None:
        self.poly([(x0, y0), (x1, y0), (x1, y1), (x0, y1)], color)

    def disc(self, center, radius: float, color: BGR, thickness: float = -1) -> None:
        c = _fp(self.px(center))[0]
        t = -1 if thickness < 0 else max(1, int(round(thickness * self.r)))
        cv2.circle(self.img, (int(c[0]), int(c[1])), int(round(radius * self.r * (1 << _SHIFT))),
                   (*color, 255), t, cv2.LINE_AA, _SHIFT)

    def line(self, p0, p1, width: float, color: BGR) -> None:
        a, b = _fp(self.px([p0, p1]))
        cv2.line(self.img, (int(a[0]), int(a[1])), (int(b[0]), int(b[1])), (*color, 255),
                 max(1, int(round(width * self.r))), cv2.LINE_AA, _SHIFT)

    def text(self, s: str, font: int, center, box_wh, color: BGR) -> None:
        """Stretch ``s`` to fill a box of ``box_wh`` unit size centred at ``center``."""
        if not s.strip():
            return
        m = _glyph_mask(s, font)
        cx, cy = self.px(center)[0]
        bw, bh = box_wh[0] * self.k[0], box_wh[1] * self.k[1]
        aspect = m.shape[0] / m.shape[1]  # shrink the box so glyphs distort at most 1.5x
        bh, bw = min(bh, 1.5 * aspect * bw), min(bw, 1.5 * bh / aspect)
        bw, bh = max(1, int(round(bw))), max(1, int(round(bh)))
        interp = cv2.INTER_AREA if bw < m.shape[1] else cv2.INTER_LINEAR
        m = cv2.resize(m, (bw, bh), interpolation=interp)
        x0, y0 = int(round(cx - bw / 2)), int(round(cy - bh / 2))
        X0, Y0 = max(x0, 0), max(y0, 0)
        X1, Y1 = min(x0 + bw, self.img.shape[1]), min(y0 + bh, self.img.shape[0])
        if X1 <= X0 or Y1 <= Y0:
            return
        a = m[Y0 - y0:Y1 - y0, X0 - x0:X1 - x0, None]
        roi = self.img[Y0:Y1, X0:X1, :3].astype(np.float32)
        roi += (np.float32(color) - roi) * a
        self.img[Y0:Y1, X0:X1, :3] = np.round(roi).astype(np.uint8)

    def finish(self) -> np.ndarray:
        return cv2.resize(self.img, (self.w, self.h), interpolation=cv2.INTER_AREA)


def _octagon(r: float = 1.0) -> np.ndarray:
    """Regular octagon with flat sides at distance ``r`` (fills ~0.83 of its square)."""
    a = np.deg2rad(22.5 + 45.0 * np.arange(8))
    return np.stack([np.cos(a), np.sin(a)], 1) * (r / np.cos(np.deg2rad(22.5)))


def _jitter(amount: float, rng: np.random.Generator | None) -> np.ndarray:
    if amount <= 0:
        return np.zeros(_N_JIT)
    rng = rng if rng is not None else np.random.default_rng(0)  # deterministic default
    return amount * rng.uniform(-1.0, 1.0, _N_JIT)


def _arrow(turn: int, w: float, jit: np.ndarray) -> np.ndarray:
    """Unit-coord polygon of a thick arrow going up from the bottom centre.

    ``turn`` -1/+1 bends it 90 degrees left/right through a rounded corner, 0 keeps it
    straight. Built as a single polygon (stroke offset + head) so LINE_AA leaves no seam.
    Left is built as the exact mirror of right so the two classes differ only by a flip.
    """
    w *= 1 + 0.15 * jit[0]
    hh = (0.9 * w + 0.08) * (1 + 0.12 * jit[1])  # head half-width
    hl = 1.1 * hh * (1 + 0.1 * jit[2])  # head length
    if turn == 0:
        line = np.array([(0.0, 0.62), (0.0, -0.62 + hl)])
    else:
        sx, cy, tip = -0.28, -0.16 + 0.06 * jit[3], 0.6
        hx = tip - hl
        rb = max(0.5 * w, min(0.8 * w, hx - sx - 0.02))  # >= w/2: inner edge never folds
        ang = np.linspace(np.pi, 1.5 * np.pi, 7)
        arc = np.stack([sx + rb + rb * np.cos(ang), cy + rb + rb * np.sin(ang)], 1)
        line = np.vstack([(sx, 0.62), arc, (max(hx, sx + rb + 1e-3), cy)])
    seg = np.diff(line, axis=0)
    seg /= np.linalg.norm(seg, axis=1, keepdims=True)
    tan = np.vstack([seg[:1], seg[:-1] + seg[1:], seg[-1:]])
    tan /= np.linalg.norm(tan, axis=1, keepdims=True)
    nrm = np.stack([-tan[:, 1], tan[:, 0]], 1)
    end, t_end, n_end = line[-1], tan[-1], nrm[-1]
    head = np.array([end + n_end * hh, end + t_end * hl, end - n_end * hh])
    poly = np.vstack([line + nrm * w / 2, head, (line - nrm * w / 2)[::-1]])
    th = np.deg2rad(6.0 * jit[4])  # small rotation + shift: hand-painted variation
    rot = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    poly = poly @ rot.T + 0.05 * jit[5:7]
    if turn < 0:
        poly[:, 0] *= -1
    return poly


_TURN = {"left": -1, "no_left": -1, "right": 1, "no_right": 1, "straight": 0}


def draw_sign(name: str, size: int, style: SignStyle | None = None,
              rng: np.random.Generator | None = None) -> np.ndarray:
    """Draw one of :data:`SIGN_NAMES` as a ``uint8`` ``(size, size, 4)`` B,G,R,A sprite.

    The face (disc or octagon) is inscribed in the square and touches its edges; alpha is
    255 on it, 0 outside. ``rng`` only drives ``style.stroke_jitter`` (seed 0 if None).
    """
    if name not in SIGN_NAMES:
        raise ValueError(f"unknown sign name {name!r}; expected one of {SIGN_NAMES}")
    if size < 1:
        raise ValueError(f"size must be >= 1, got {size}")
    size = int(size)
    st = _faded(style or SignStyle())
    jit = _jitter(st.stroke_jitter, rng)
    b = float(np.clip(st.border_frac, 0.0, 0.5))
    aw = 2.0 * st.arrow_width_frac  # sprite size is 2 units
    if name == "stop":
        pad = _Pad(size, size, st.white if b > 0 else st.red)
        pad.poly(_octagon(), st.white)  # sets the face alpha
        pad.poly(_octagon(1 - b), st.red)
        s = (1 - b) * (1 + 0.08 * jit[0])
        pad.text(st.stop_word, st.font, 0.05 * jit[5:7], (1.45 * s, 0.52 * s), st.white)
    elif name.startswith("no_"):
        ring = float(np.clip(st.ring_frac, 0.02, 0.6))
        pad = _Pad(size, size, st.red)
        pad.disc((0, 0), 1.0, st.red)
        pad.disc((0, 0), 1 - ring, st.white)
        pad.poly(_arrow(_TURN[name], aw, jit) * (0.86 * (1 - ring)), st.black)
        d = (1 - ring) / np.sqrt(2)  # slash ends on the ring, top-left to bottom-right
        pad.line((-d, -d), (d, d), 0.8 * ring, st.red)
    else:
        pad = _Pad(size, size, st.white if b > 0 else st.blue)
        pad.disc((0, 0), 1.0, st.white if b > 0 else st.blue)
        pad.disc((0, 0), 1 - b, st.blue)
        pad.poly(_arrow(_TURN[name], aw, jit) * ((1 - b) / 0.95), st.white)
    return pad.finish()


def sign_face_mask(sprite: np.ndarray) -> np.ndarray:
    """Bool ``(h, w)`` mask of the sprite's face: alpha channel > 127."""
    return sprite[..., 3] > 127


# --------------------------------------------------------------------------- distractors
def _u(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(rng.uniform(lo, hi))


def _rand_bgr(rng: np.random.Generator, lo: int = 0, hi: int = 256) -> BGR:
    return tuple(int(c) for c in rng.integers(lo, hi, 3))


def _red_disc(size: int, rng: np.random.Generator, st: SignStyle) -> np.ndarray:
    variant = int(rng.integers(3))  # filled / ring on white / ring on blue
    pad = _Pad(size, size, st.red)
    pad.disc((0, 0), 1.0, st.red)
    if variant > 0:
        inner = st.white if variant == 1 else st.blue
        pad.disc((0, 0), 1 - st.ring_frac * _u(rng, 0.8, 1.5), inner)
    return pad.finish()


def _blue_disc(size: int, rng: np.random.Generator, st: SignStyle) -> np.ndarray:
    rim = st.white if st.border_frac > 0.02 else st.blue
    pad = _Pad(size, size, rim)
    pad.disc((0, 0), 1.0, rim)
    pad.disc((0, 0), 1 - st.border_frac, st.blue)
    symbol = int(rng.integers(5))  # deliberately no arrows and no vertical bars
    if symbol == 0:
        pad.rect(-0.6, -0.13, 0.6, 0.13, st.white)
    elif symbol == 1:
        pad.disc((0, 0), _u(rng, 0.35, 0.6), st.white, thickness=_u(rng, 0.1, 0.2))
    elif symbol == 2:
        pad.disc((0, 0), _u(rng, 0.15, 0.35), st.white)
    elif symbol == 3:
        pad.rect(-0.6, -0.35, 0.6, -0.12, st.white)
        pad.rect(-0.6, 0.12, 0.6, 0.35, st.white)
    else:
        letter = str(rng.choice(["P", "H", "i", "30", "50", "M"]))
        pad.text(letter, st.font, (0, 0), (0.45 * len(letter), 0.9), st.white)
    return pad.finish()


def _blue_rect(size: int, rng: np.random.Generator, st: SignStyle) -> np.ndarray:
    pad = _Pad(size, max(1, round(size * _u(rng, 0.7, 1.8))), st.white)
    pad.rect(-1, -1, 1, 1, st.white)
    e = _u(rng, 0.03, 0.1)
    pad.rect(-1 + e, -1 + e, 1 - e, 1 - e, st.blue)
    words = ["P", "INFO", "EXIT", "BUS", "H", "200m", "PARK", "ZONE", "A1", "CITY"]
    if rng.random() < 0.5:
        pad.text(str(rng.choice(words)), st.font, (0, -0.35), (1.2, 0.55), st.white)
        pad.rect(-0.8, 0.2, 0.8, 0.3, st.white)
        pad.text(str(rng.choice(words)), st.font, (0, 0.6), (0.9, 0.35), st.white)
    else:
        pad.text(str(rng.choice(words[:5])), st.font, (0, 0), (1.3, 1.2), st.white)
    return pad.finish()


def _no_entry(size: int, rng: np.random.Generator, st: SignStyle) -> np.ndarray:
    """Red disc with a white bar: a real sign outside our classes that, small or blurred, looks
    much like a stop sign (red face, white band across the middle)."""
    pad = _Pad(size, size, st.red)
    pad.disc((0, 0), 1.0, st.red)
    half_h = _u(rng, 0.12, 0.2)
    pad.rect(-0.72, -half_h, 0.72, half_h, st.white)
    return pad.finish()


def _billboard(size: int, rng: np.random.Generator, st: SignStyle) -> np.ndarray:
    pad = _Pad(size, max(1, round(size * _u(rng, 1.3, 2.6))), st.black)
    pad.rect(-1, -1, 1, 1, st.black)  # frame
    pad.rect(-0.95, -0.93, 0.95, 0.93, _rand_bgr(rng))
    for _ in range(int(rng.integers(2, 6))):
        x, y = _u(rng, -0.95, 0.6), _u(rng, -0.93, 0.5)
        pad.rect(x, y, min(0.95, x + _u(rng, 0.2, 0.9)), min(0.93, y + _u(rng, 0.2, 0.8)),
                 _rand_bgr(rng))
    if rng.random() < 0.6:  # sign-coloured areas make it a hard negative
        col = st.red if rng.random() < 0.5 else st.blue
        if rng.random() < 0.5:
            pad.disc((_u(rng, -0.6, 0.6), _u(rng, -0.3, 0.3)), _u(rng, 0.3, 0.7), col)
        else:
            pad.rect(-0.95, _u(rng, -0.9, 0.2), _u(rng, -0.2, 0.95), 0.93, col)
    letters = np.array(list("ABCDEFGHJKLMNOPRSTUVWXYZ0123456789"))
    word = "".join(rng.choice(letters, int(rng.integers(3, 8))))
    pad.text(word, st.font, (_u(rng, -0.2, 0.2), _u(rng, -0.5, 0.5)), (1.3, 0.4), _rand_bgr(rng))
    return pad.finish()


def _warning_triangle(size: int, rng: np.random.Generator, st: SignStyle) -> np.ndarray:
    pad = _Pad(size, size, st.red)
    h = np.sqrt(3.0) / 2  # equilateral triangle spanning the full width
    pad.poly([(0, -h), (1, h), (-1, h)], st.red)
    t = _u(rng, 0.18, 0.3)  # inset keeps the red band of even width
    x = 1 - t * np.sqrt(3)
    pad.poly([(0, -h + 2 * t), (x, h - t), (-x, h - t)], st.white)
    pad.poly([(-0.07, -0.2), (0.07, -0.2), (0.04, 0.38), (-0.04, 0.38)], st.black)
    pad.disc((0, 0.55), 0.075, st.black)
    return pad.finish()


def _cone(size: int, rng: np.random.Generator, st: SignStyle) -> np.ndarray:
    orange = _hsv_jitter((0, 100, 240), rng, 1.0, 6, 0.2, 0.3)
    pad = _Pad(size, max(1, round(size * _u(rng, 0.55, 0.7))), orange)
    xw = lambda y: 0.12 + (y + 0.95) / 1.67 * 0.63  # noqa: E731  half-width of body at y
    pad.poly([(-0.12, -0.95), (0.12, -0.95), (0.75, 0.72), (-0.75, 0.72)], orange)
    y0, y1 = sorted((_u(rng, -0.45, -0.1), _u(rng, -0.05, 0.3)))
    pad.poly([(-xw(y0), y0), (xw(y0), y0), (xw(y1), y1), (-xw(y1), y1)], st.white)
    shade = tuple(int(c * 0.7) for c in orange)  # darker right flank: suggests a round body
    pad.poly([(0.06, -0.95), (0.12, -0.95), (0.75, 0.72), (0.35, 0.72)], shade)
    pad.rect(-1, 0.72, 1, 0.97, tuple(int(c * 0.55) for c in orange))
    return pad.finish()


def _box(size: int, rng: np.random.Generator, st: SignStyle) -> np.ndarray:
    base = [(40, 75, 130), (30, 60, 105), st.red, st.blue][int(rng.integers(4))]
    base = _hsv_jitter(base, rng, 1.0, 4, 0.2, 0.25)
    dark = tuple(int(c * 0.55) for c in base)
    light = tuple(int(min(255, c * 1.3 + 10)) for c in base)
    pad = _Pad(size, max(1, round(size * _u(rng, 0.8, 1.4))), dark)
    pad.rect(-1, -1, 1, 1, dark)  # bottom/right edges stay dark
    lit = [(-1, -1), (1, -1), (0.9, -0.9), (-0.9, -0.9), (-0.9, 0.9), (-1, 1)]
    pad.poly(lit, light)  # lit top/left bevel
    pad.rect(-0.9, -0.9, 0.9, 0.9, base)
    for y in np.linspace(-0.9, 0.9, int(rng.integers(3, 6)) + 1)[1:-1]:
        pad.line((-0.9, y), (0.9, y), 0.03, dark)  # plank gaps
    if rng.random() < 0.5:
        pad.line((-0.85, 0.85), (0.85, -0.85), 0.12, light)  # diagonal brace
    return pad.finish()


_DISTRACTORS = {
    "red_disc": _red_disc, "blue_disc": _blue_disc, "blue_rect": _blue_rect,
    "no_entry": _no_entry, "billboard": _billboard,
    "warning_triangle": _warning_triangle, "cone": _cone, "box": _box,
}


def draw_distractor(kind: str, size: int, rng: np.random.Generator) -> np.ndarray:
    """Draw a hard-negative sprite of ``kind`` (see :data:`DISTRACTOR_KINDS`).

    Returns ``uint8`` ``(size, w, 4)`` B,G,R,A: height is ``size``; width depends on the
    kind (billboards are wider than tall, cones narrower). Deterministic given ``rng`` state.
    """
    if kind not in _DISTRACTORS:
        raise ValueError(f"unknown distractor kind {kind!r}; expected one of {DISTRACTOR_KINDS}")
    if size < 1:
        raise ValueError(f"size must be >= 1, got {size}")
    return _DISTRACTORS[kind](int(size), rng, _faded(random_style(rng)))
