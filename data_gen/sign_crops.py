"""Image operations behind the sign-crop dataset: proposal-like crops, colour regions, sprites.

Boxes are (x, y, w, h) in image pixels unless a name says xyxy. Images are uint8 BGR.
"""
from __future__ import annotations

import math
from dataclasses import replace

import cv2
import numpy as np

from signlane.signs.proposals import propose
from signlane.world.art import draw_distractor, draw_sign, random_style
from signlane.world.render import Sample

Box = tuple[int, int, int, int]

SIGN_MIN_PX = 12  # smaller faces carry no readable symbol
MAX_OCCLUDED = 0.5
MAX_TRUNCATED = 0.5  # a sign mostly outside the frame is not a fair example of its class
# grey-level spread (95th - 5th percentile) the middle of a face needs: below it exposure, glare,
# fog or blur have washed the symbol into a flat patch nobody can read (the sprites' exposure cap,
# for frames); 12 drops about 5 % of frame signs, all of them blank or pure noise when looked at
MIN_FACE_CONTRAST = 12.0
# correlation a face's middle must keep with itself before the camera's effects (motion blur,
# noise, glare, rain, JPEG), both smoothed at the scale of the symbol's strokes: below it the
# effects have smeared the symbol into a blob nobody can read (about 8 % of frame signs; looked
# at, most of those under 0.9 are blobs, with a few faint but readable signs among them)
MIN_SYMBOL_SURVIVAL = 0.9
UNKNOWN_MIN_PX = 10
PAD_MAX = 0.25  # crops look like imperfect proposals: 0-25 % padding per side ...
SHIFT_MAX = 0.10  # ... and the box centre off by up to 10 % of its size
SIGN_IOU = 0.3  # an unknown candidate this close to a sign would be a mislabelled sign crop
PROPOSAL_IOU = 0.5  # a proposal matching a sign this well takes its class
SPRITE_PX = (12, 120)  # sprite face size range (log-uniform): far signs to ones close to the camera
YAW_MAX_DEG = 60.0  # signs seen this far off their axis still count
OCCLUDE_PROB = 0.15
# distractor kinds of the unknown sprites: the sign-like ones (what the classifier confuses with
# signs) drawn more often than cones and boxes, which no colour proposal mistakes for a sign.
# There is no red octagon among them: a red octagon means stop to every road user whatever its
# word, so the classifier must not learn to read the word (small or blurred, nobody can)
UNKNOWN_KIND_WEIGHTS = {"no_entry": 3, "red_disc": 3, "blue_disc": 2.5, "blue_rect": 2.5,
                        "warning_triangle": 1, "billboard": 1, "cone": 0.5, "box": 0.5}
# the word on stop sprites: mostly STOP (VIA's and our renderer's), also other countries' words,
# so that the octagon, not one word, is what the classifier learns (never blank: a blank red
# octagon, small or blurred, would be a filled red disc, which is no sign)
STOP_WORDS = {"STOP": 0.75, "ALTO": 0.09, "PARE": 0.08, "ARRET": 0.08}
# HSV thresholds of sign paint (OpenCV hue 0..180), the same regions a colour proposal stage finds
RED_LO = ((0, 70, 50), (10, 255, 255))
RED_HI = ((170, 70, 50), (180, 255, 255))
BLUE = ((100, 150, 0), (140, 255, 255))


def jitter_box(box: Box, rng: np.random.Generator) -> tuple[float, float, float, float]:
    """An imperfect proposal around `box`: each side padded by 0-PAD_MAX of the box size, then
    shifted by up to SHIFT_MAX; returns float xyxy (may leave the image)."""
    x, y, w, h = box
    pl, pt, pr, pb = rng.uniform(0, PAD_MAX, 4)
    dx, dy = rng.uniform(-SHIFT_MAX, SHIFT_MAX, 2)
    return (x - pl * w + dx * w, y - pt * h + dy * h, x + w + pr * w + dx * w, y + h + pb * h + dy * h)


def crop_resize(image: np.ndarray, xyxy: tuple[float, float, float, float], size: int) -> np.ndarray:
    """Crop float xyxy from uint8 (H, W, 3) BGR `image` (edge pixels repeated where the box
    leaves the image) and resize to uint8 (size, size, 3) BGR."""
    x0, y0, x1, y1 = (int(round(v)) for v in xyxy)
    x1, y1 = max(x1, x0 + 1), max(y1, y0 + 1)
    h, w = image.shape[:2]
    pad = max(0, -x0, -y0, x1 - w, y1 - h)
    if pad:
        image = cv2.copyMakeBorder(image, pad, pad, pad, pad, cv2.BORDER_REPLICATE)
        x0, y0, x1, y1 = x0 + pad, y0 + pad, x1 + pad, y1 + pad
    roi = image[y0:y1, x0:x1]
    interp = cv2.INTER_AREA if roi.shape[0] > size and roi.shape[1] > size else cv2.INTER_LINEAR
    return cv2.resize(roi, (size, size), interpolation=interp)


def iou(a: Box, b: Box) -> float:
    """Intersection over union of two (x, y, w, h) boxes."""
    ix = max(0, min(a[0] + a[2], b[0] + b[2]) - max(a[0], b[0]))
    iy = max(0, min(a[1] + a[3], b[1] + b[3]) - max(a[1], b[1]))
    inter = ix * iy
    union = a[2] * a[3] + b[2] * b[3] - inter
    return inter / union if union > 0 else 0.0


def covers_sign(box: Box, signs: list[Box]) -> bool:
    """True when `box` is (a large part of) a sign: IoU >= SIGN_IOU, or half of either box is
    the other (a fragment such as the red ring, or a big box around a small sign)."""
    for s in signs:
        ix = max(0, min(box[0] + box[2], s[0] + s[2]) - max(box[0], s[0]))
        iy = max(0, min(box[1] + box[3], s[1] + s[3]) - max(box[1], s[1]))
        inter = ix * iy
        if iou(box, s) >= SIGN_IOU or inter >= 0.5 * min(box[2] * box[3], s[2] * s[3]):
            return True
    return False


def colour_regions(image: np.ndarray, min_px: int = UNKNOWN_MIN_PX) -> list[Box]:
    """Boxes of connected red or blue regions (HSV thresholds above) in uint8 (H, W, 3) BGR
    `image`, at least `min_px` on each side, in a stable order (top to bottom, left to right)."""
    hsv = cv2.cvtColor(image, cv2.COLOR_BGR2HSV)
    red = cv2.inRange(hsv, *RED_LO) | cv2.inRange(hsv, *RED_HI)
    boxes = []
    for mask in (red, cv2.inRange(hsv, *BLUE)):
        # closing joins a sign's ring across its white inside so one region = one object
        mask = cv2.morphologyEx(mask, cv2.MORPH_CLOSE, np.ones((3, 3), np.uint8))
        # outer contours = 8-connected regions, holes ignored; ~50x faster than labelling them
        contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
        for x, y, w, h in map(cv2.boundingRect, contours):
            if min(w, h) >= min_px and max(w, h) <= 4 * min(w, h):
                boxes.append((int(x), int(y), int(w), int(h)))
    return sorted(boxes, key=lambda b: (b[1], b[0]))


def background_box(rng: np.random.Generator, shape: tuple[int, ...], avoid: list[Box],
                   side: tuple[int, int] = (16, 96), tries: int = 10) -> Box | None:
    """A random square box inside an image of `shape` that touches none of `avoid`."""
    h, w = shape[:2]
    for _ in range(tries):
        hi = min(side[1], h, w)
        s = int(rng.integers(min(side[0], hi), hi + 1))
        b = (int(rng.integers(0, w - s + 1)), int(rng.integers(0, h - s + 1)), s, s)
        if all(iou(b, a) == 0 and not _touches(b, a) for a in avoid):
            return b
    return None


def _touches(a: Box, b: Box) -> bool:
    return a[0] < b[0] + b[2] and b[0] < a[0] + a[2] and a[1] < b[1] + b[3] and b[1] < a[1] + a[3]


def face_contrast(image: np.ndarray, box: Box) -> float:
    """Grey-level spread (95th - 5th percentile, 0..255) of the middle half of box (x, y, w, h) in
    uint8 (H, W, 3) BGR `image`, where a sign's symbol is (its corners are background), after a
    blur that removes pixel noise but keeps a symbol; 0 for a box outside the image."""
    x, y, w, h = box
    roi = image[max(0, y + h // 4):max(0, y + h - h // 4), max(0, x + w // 4):max(0, x + w - w // 4)]
    if roi.size == 0:
        return 0.0
    grey = cv2.GaussianBlur(cv2.cvtColor(roi, cv2.COLOR_BGR2GRAY).astype(np.float32), (0, 0), max(0.7, w / 20))
    lo, hi = np.percentile(grey, (5, 95))
    return float(hi - lo)


def symbol_survival(sample: Sample, box: Box) -> float:
    """Correlation (-1..1) between the middle half of box (x, y, w, h), where a sign's symbol is,
    in the frame before and after the camera's photometric effects, both smoothed at the scale
    of the symbol's strokes (a little pixel noise averages out, a smeared symbol does not);
    1.0 for a sample without the clean frame, 0.0 where the middle is flat or off the image."""
    if sample.clean is None:
        return 1.0
    x, y, w, h = box
    sigma = max(0.5, w / 32)
    m = int(math.ceil(3 * sigma))  # margin so the smoothing sees the same pixels in both
    hgt, wid = sample.image.shape[:2]
    x0, y0 = max(0, x + w // 4 - m), max(0, y + h // 4 - m)
    x1, y1 = min(wid, x + w - w // 4 + m), min(hgt, y + h - h // 4 + m)
    if x1 - x0 <= 2 * m or y1 - y0 <= 2 * m:
        return 0.0
    a, b = (cv2.GaussianBlur(cv2.cvtColor(img[y0:y1, x0:x1], cv2.COLOR_BGR2GRAY).astype(np.float32), (0, 0), sigma)
            [m:-m, m:-m].ravel() for img in (sample.clean, sample.image))
    a, b = a - a.mean(), b - b.mean()
    norm = float(np.sqrt((a * a).sum() * (b * b).sum()))
    return float((a * b).sum() / norm) if norm > 0 else 0.0


def usable_sign(sign, sample: Sample) -> bool:
    """A ground-truth SignTruth big, visible and legible enough in `sample` (the frame it was
    rendered in) to be an example of its class."""
    return min(sign.box[2], sign.box[3]) >= SIGN_MIN_PX and sign.occluded <= MAX_OCCLUDED \
        and sign.truncated <= MAX_TRUNCATED and face_contrast(sample.image, sign.box) >= MIN_FACE_CONTRAST \
        and symbol_survival(sample, sign.box) >= MIN_SYMBOL_SURVIVAL


def unknown_candidates(sample: Sample, rng: np.random.Generator) -> list[Box]:
    """Unknown-class boxes of a frame, interleaved by source (distractors, colour regions,
    background) so a small per-frame quota still sees every kind; none covers a sign."""
    signs = [s.box for s in sample.truth.signs]
    distractors = [b for _, b in sample.truth.distractors
                   if min(b[2], b[3]) >= UNKNOWN_MIN_PX and not covers_sign(b, signs)]
    colour = [b for b in colour_regions(sample.image)
              if not covers_sign(b, signs) and all(iou(b, d) < 0.5 for d in distractors)]
    bg = background_box(rng, sample.image.shape, signs)
    sources = [list(rng.permutation(len(distractors))), list(rng.permutation(len(colour))), [0] if bg else []]
    lists = [distractors, colour, [bg]]
    out: list[Box] = []
    while any(sources):
        for k, order in enumerate(sources):
            if order:
                out.append(lists[k][int(order.pop(0))])
    return out


def proposal_labels(sample: Sample) -> list[tuple[str, Box]]:
    """The colour-mask proposals of a frame, each labelled by its overlap with the ground truth:
    IoU >= PROPOSAL_IOU with a usable sign takes that sign's class, no overlap with any sign is
    'unknown'; a proposal that touches a sign without matching it (a fragment, or a sign too
    hidden or washed out to be an example) is left out rather than given a wrong label."""
    out = []
    sign_boxes = [s.box for s in sample.truth.signs]
    for prop in propose(sample.image):
        best = max(sample.truth.signs, key=lambda s: iou(prop.box, s.box), default=None)
        if best is not None and iou(prop.box, best.box) >= PROPOSAL_IOU:
            if usable_sign(best, sample):
                out.append((best.label, prop.box))
        elif not covers_sign(prop.box, sign_boxes):
            out.append(("unknown", prop.box))
    return out


def frame_crops(sample: Sample, rng: np.random.Generator, unknown_quota: int,
                size: int) -> list[tuple[str, np.ndarray]]:
    """(label, uint8 (size, size, 3) BGR crop): the frame's proposals exactly as the runtime crops
    them (labelled by ground truth), jittered crops of its usable signs (proposals miss some),
    then other unknowns up to `unknown_quota` in all."""
    labelled = proposal_labels(sample)
    out = [(label, crop_resize(sample.image, (x, y, x + w, y + h), size)) for label, (x, y, w, h) in labelled]
    out += [(s.label, crop_resize(sample.image, jitter_box(s.box, rng), size))
            for s in sample.truth.signs if usable_sign(s, sample)]
    taken = [b for label, b in labelled if label == "unknown"]
    room = max(0, unknown_quota - len(taken))
    for box in [b for b in unknown_candidates(sample, rng) if all(iou(b, t) < 0.5 for t in taken)][:room]:
        out.append(("unknown", crop_resize(sample.image, jitter_box(box, rng), size)))
    return out


def _perspective(sprite: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Warp a uint8 (s, w, 4) BGRA sprite as a camera sees a sign standing up to 60 degrees off
    its axis (foreshortened, the near edge taller), tilted a little; returns a BGRA canvas with a
    margin of transparent pixels around it."""
    h, w = sprite.shape[:2]
    # repeat the edge colour under alpha 0 so interpolation brings in no black fringe
    sprite = cv2.copyMakeBorder(sprite, 2, 2, 2, 2, cv2.BORDER_REPLICATE)
    sprite[:2, :, 3] = sprite[-2:, :, 3] = sprite[:, :2, 3] = sprite[:, -2:, 3] = 0
    m = int(math.ceil(0.35 * max(h, w)))
    src = np.float32([[2, 2], [w + 2, 2], [w + 2, h + 2], [2, h + 2]])
    yaw = math.radians(rng.uniform(-YAW_MAX_DEG, YAW_MAX_DEG))
    squeeze = math.cos(yaw)  # the face's width as seen from the side
    near = 1.0 + 0.25 * abs(math.sin(yaw))  # the nearer edge looks taller
    c = np.array([w / 2, h / 2])
    corners = (src - 2 - c) * np.array([squeeze, 1.0])
    side = 1 if yaw > 0 else 0  # which vertical edge is nearer
    for k in ((1, 2) if side else (0, 3)):
        corners[k, 1] *= near
    a = math.radians(rng.uniform(-8, 8))
    rot = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    dst = corners @ rot.T + c + m + rng.uniform(-0.06, 0.06, (4, 2)) * np.array([w, h])
    M = cv2.getPerspectiveTransform(src, dst.astype(np.float32))
    return cv2.warpPerspective(sprite, M, (w + 2 * m, h + 2 * m), flags=cv2.INTER_LINEAR,
                               borderMode=cv2.BORDER_REPLICATE)


def _occlude(img: np.ndarray, face: Box, rng: np.random.Generator) -> None:
    """Cover a band at one side of the face with a branch, pole or another object's colour (in place)."""
    x, y, w, h = face
    # at most a quarter of the width from one side: covering more would hide the arrow's
    # head or the word, and a sign nobody can read is no example of its class
    ow, oh = int(w * rng.uniform(0.12, 0.25)), int(h * rng.uniform(0.15, 0.6))
    ox = x + (0 if rng.random() < 0.5 else w - ow)
    oy = y + int(rng.uniform(0, max(1, h - oh)))
    colour = tuple(int(v) for v in rng.integers(20, 200, 3))
    cv2.rectangle(img, (ox, oy), (ox + ow, oy + oh), colour, -1)


def _camera_look(img: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Exposure, colour cast and JPEG of another camera; uint8 BGR in and out."""
    gain = float(np.clip(2.0 ** rng.normal(0, 0.45), 0.4, 2.2))  # beyond this a sign is a white or black patch
    cast = 1.0 + rng.normal(0, 0.08, 3)
    out = np.clip(img.astype(np.float32) * gain * cast, 0, 255).astype(np.uint8)
    if rng.random() < 0.4:
        ok, buf = cv2.imencode(".jpg", out, [cv2.IMWRITE_JPEG_QUALITY, int(rng.integers(15, 90))])
        out = cv2.imdecode(buf, cv2.IMREAD_COLOR)
    return out


def _sprite_for(name: str, size: int, rng: np.random.Generator) -> np.ndarray:
    if name == "unknown":
        kinds = list(UNKNOWN_KIND_WEIGHTS)
        p = np.array([UNKNOWN_KIND_WEIGHTS[k] for k in kinds], float)
        return draw_distractor(kinds[int(rng.choice(len(kinds), p=p / p.sum()))], size, rng)
    style = random_style(rng, float(rng.uniform(0.2, 1.0)))
    if name == "stop":
        words = list(STOP_WORDS)
        style = replace(style, stop_word=words[int(rng.choice(len(words), p=list(STOP_WORDS.values())))])
    return draw_sign(name, size, style, rng)


def sprite_crop(name: str, rng: np.random.Generator, background: Sample, size: int) -> np.ndarray:
    """A crop of class `name` rendered from the sprite art (a distractor for "unknown") at a
    random scale and viewpoint on a patch of `background`'s image, lit, blurred and noised to
    match the rendered frames; uint8 (size, size, 3) BGR."""
    bg_img = background.image
    signs = [s.box for s in background.truth.signs]
    if name == "unknown" and rng.random() < 0.25:  # plain scenery is an unknown proposal too
        box = background_box(rng, bg_img.shape, signs) or (0, 0, 32, 32)
        return crop_resize(bg_img, jitter_box(box, rng), size)
    px = int(round(math.exp(rng.uniform(math.log(SPRITE_PX[0]), math.log(SPRITE_PX[1])))))
    warped = _perspective(_sprite_for(name, px, rng), rng)
    fit = min(1.0, (bg_img.shape[1] - 1) / warped.shape[1], (bg_img.shape[0] - 1) / warped.shape[0])
    if fit < 1.0:  # a near billboard, wider than the frame once warped: the camera sees part of it
        warped = cv2.resize(warped, None, fx=fit, fy=fit, interpolation=cv2.INTER_AREA)
        px = max(1, int(px * fit))
    ch, cw = warped.shape[:2]
    spot = background_box(rng, bg_img.shape, signs, side=(max(ch, cw), max(ch, cw))) \
        if max(ch, cw) <= min(bg_img.shape[:2]) else None
    if spot is None:
        spot = (int(rng.integers(0, bg_img.shape[1] - cw + 1)), int(rng.integers(0, bg_img.shape[0] - ch + 1)))
    patch = bg_img[spot[1]:spot[1] + ch, spot[0]:spot[0] + cw].astype(np.float32)
    alpha = warped[:, :, 3:4].astype(np.float32) / 255.0
    colour = warped[:, :, :3].astype(np.float32) * rng.uniform(0.6, 1.15)  # scene lighting
    img = patch * (1 - alpha) + colour * alpha
    sigma = rng.uniform(0, 1.0) * px / 32  # blur in proportion to size: the renderer's look
    if sigma > 0.3:
        img = cv2.GaussianBlur(img, (0, 0), sigma)
    img = np.clip(img + rng.normal(0, rng.uniform(0, 8), img.shape), 0, 255).astype(np.uint8)
    ys, xs = np.nonzero(warped[:, :, 3] > 127)
    face = (int(xs.min()), int(ys.min()), int(np.ptp(xs)) + 1, int(np.ptp(ys)) + 1) if len(xs) else (0, 0, cw, ch)
    if rng.random() < OCCLUDE_PROB:
        _occlude(img, face, rng)
    return _camera_look(crop_resize(img, jitter_box(face, rng), size), rng)
