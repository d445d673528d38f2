"""Per-frame domain randomisation: camera-pose jitter and photometric effects, all seeded."""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import cv2
import numpy as np

from signlane.camera import Camera


@dataclass(frozen=True)
class Effects:
    """Amounts of randomisation (0 = off). Probabilities are per frame."""

    exposure: float = 0.0  # std of log2 exposure gain
    gamma: float = 0.0  # std of log gamma
    color_cast: float = 0.0  # std of per-channel gain
    glare_prob: float = 0.0
    motion_blur_prob: float = 0.0
    motion_blur_px: float = 6.0
    noise: float = 0.0  # max sensor noise sigma, 0..255 units
    jpeg_prob: float = 0.0
    jpeg_quality: tuple[int, int] = (35, 95)
    pitch_deg: float = 0.0  # std of camera pose jitter
    roll_deg: float = 0.0
    height_m: float = 0.0
    yaw_deg: float = 0.0
    night_prob: float = 0.0  # dark frame lit by headlights: low gain, bluish cast, more noise
    rain_prob: float = 0.0  # wet haze, softened detail and streaks on the lens

    @classmethod
    def clean(cls) -> "Effects":
        return cls()

    @classmethod
    def normal(cls) -> "Effects":
        return cls(exposure=0.25, gamma=0.1, color_cast=0.04, glare_prob=0.05, motion_blur_prob=0.1,
                   noise=4.0, jpeg_prob=0.3, pitch_deg=1.0, roll_deg=1.0, height_m=0.03, yaw_deg=1.0)

    @classmethod
    def hard(cls) -> "Effects":
        return cls(exposure=0.6, gamma=0.25, color_cast=0.1, glare_prob=0.3, motion_blur_prob=0.35,
                   motion_blur_px=10.0, noise=12.0, jpeg_prob=0.6, jpeg_quality=(15, 80), pitch_deg=2.0,
                   roll_deg=2.5, height_m=0.08, yaw_deg=2.0)

    @classmethod
    def heavy(cls) -> "Effects":
        """Beyond `hard`: night-ish exposure and rain on top of stronger light, blur and pose
        changes (for training sets that must generalise past the renderer)."""
        return cls(exposure=0.8, gamma=0.35, color_cast=0.15, glare_prob=0.3, motion_blur_prob=0.35,
                   motion_blur_px=12.0, noise=14.0, jpeg_prob=0.6, jpeg_quality=(15, 85), pitch_deg=2.5,
                   roll_deg=3.0, height_m=0.1, yaw_deg=2.5, night_prob=0.25, rain_prob=0.25)

    @classmethod
    def named(cls, name: str) -> "Effects":
        try:
            return {"clean": cls.clean, "normal": cls.normal, "hard": cls.hard, "heavy": cls.heavy}[name]()
        except KeyError:
            raise ValueError(f"unknown effects preset {name!r} (clean, normal, hard, heavy)") from None

    def jitter_camera(self, camera: Camera, rng: np.random.Generator) -> Camera:
        if not (self.pitch_deg or self.roll_deg or self.height_m or self.yaw_deg):
            return camera
        return replace(camera, pitch_deg=camera.pitch_deg + rng.normal(0, self.pitch_deg),
                       roll_deg=camera.roll_deg + rng.normal(0, self.roll_deg),
                       yaw_deg=camera.yaw_deg + rng.normal(0, self.yaw_deg),
                       height_m=max(0.2, camera.height_m + rng.normal(0, self.height_m)))


_NOISE_BANK: dict[tuple[int, int], np.ndarray] = {}


def _noise(shape: tuple[int, int, int], rng: np.random.Generator) -> np.ndarray:
    """Unit Gaussian noise from a small fixed bank (drawing fresh noise costs more than a frame)."""
    key = shape[:2]
    if key not in _NOISE_BANK:
        _NOISE_BANK[key] = np.random.default_rng(1234).standard_normal((4, *shape)).astype(np.float32)
    bank = _NOISE_BANK[key]
    n = bank[int(rng.integers(len(bank)))]
    dy, dx = int(rng.integers(shape[0])), int(rng.integers(shape[1]))
    return np.roll(n, (dy, dx), axis=(0, 1))


def apply_effects(image: np.ndarray, effects: Effects, rng: np.random.Generator) -> np.ndarray:
    """Photometric effects on uint8 BGR (H, W, 3); returns a new uint8 BGR image."""
    out = image
    if effects.exposure or effects.gamma or effects.color_cast:
        gain = 2.0 ** rng.normal(0, effects.exposure)
        gamma = math.exp(rng.normal(0, effects.gamma))
        cast = 1.0 + rng.normal(0, effects.color_cast, 3)
        x = np.arange(256, dtype=np.float32) / 255.0
        lut = np.stack([np.clip(255.0 * np.clip(x * gain * c, 0, 1) ** gamma, 0, 255) for c in cast], axis=1)
        out = cv2.LUT(out, lut.astype(np.uint8).reshape(256, 1, 3))
    # each extra draws from rng only when enabled, so the older presets keep their pixels
    if effects.night_prob and rng.random() < effects.night_prob:
        out = _night(out, rng)
    if effects.glare_prob and rng.random() < effects.glare_prob:
        out = _glare(out, rng)
    if effects.rain_prob and rng.random() < effects.rain_prob:
        out = _rain(out, rng)
    if effects.motion_blur_prob and rng.random() < effects.motion_blur_prob:
        k = max(3, int(rng.uniform(2, effects.motion_blur_px)) | 1)
        kernel = np.zeros((k, k), np.float32)
        kernel[k // 2, :] = 1.0 / k
        rot = cv2.getRotationMatrix2D((k / 2 - 0.5, k / 2 - 0.5), float(rng.uniform(0, 180)), 1.0)
        kernel = cv2.warpAffine(kernel, rot, (k, k))
        kernel /= max(kernel.sum(), 1e-6)
        out = cv2.filter2D(out, -1, kernel)
    if effects.noise:
        sigma = float(rng.uniform(0, effects.noise))
        out = cv2.add(out.astype(np.float32), _noise(out.shape, rng) * sigma, dtype=cv2.CV_8U) \
            if sigma > 0.5 else out
    if effects.jpeg_prob and rng.random() < effects.jpeg_prob:
        q = int(rng.integers(effects.jpeg_quality[0], effects.jpeg_quality[1] + 1))
        ok, buf = cv2.imencode(".jpg", out, [cv2.IMWRITE_JPEG_QUALITY, q])
        out = cv2.imdecode(buf, cv2.IMREAD_COLOR)
    return out if out is not image else image.copy()


def _glare(image: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    h, w = image.shape[:2]
    cx, cy = rng.uniform(0, w), rng.uniform(0, h * 0.6)
    r = rng.uniform(0.15, 0.6) * w
    yy, xx = np.ogrid[:h, :w]
    d2 = ((xx - cx) ** 2 + (yy - cy) ** 2) / (r * r)
    g = (rng.uniform(80, 200) * np.exp(-d2)).astype(np.float32)
    return cv2.add(image.astype(np.float32), cv2.merge([g, g, g]), dtype=cv2.CV_8U)


def _night(image: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Night-ish: the scene darkened to 10-40 %, a bluish or sodium cast, and a headlight pool
    brightening the road near the bottom centre."""
    h, w = image.shape[:2]
    yy, xx = np.ogrid[:h, :w]
    cx, cy = w * rng.uniform(0.35, 0.65), h * rng.uniform(1.0, 1.3)
    d2 = ((xx - cx) / (0.6 * w)) ** 2 + ((yy - cy) / (0.55 * h)) ** 2
    light = rng.uniform(0.1, 0.4) + rng.uniform(0.3, 0.8) * np.exp(-d2)
    cast = np.array([1.15, 1.0, 0.8] if rng.random() < 0.6 else [0.7, 0.95, 1.2], np.float32)
    gain = (light[..., None] * cast * rng.uniform(0.8, 1.1, 3)).astype(np.float32)
    out = cv2.multiply(image.astype(np.float32), gain, dtype=cv2.CV_8U)
    return cv2.add(out.astype(np.float32), _noise(out.shape, rng) * float(rng.uniform(3, 10)), dtype=cv2.CV_8U)


def _rain(image: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Rain: lower contrast towards a grey haze, softened detail, and faint streaks."""
    h, w = image.shape[:2]
    haze = float(rng.uniform(0.15, 0.45))
    grey = float(rng.uniform(110, 190))
    out = cv2.addWeighted(image, 1.0 - haze, np.full_like(image, int(grey)), haze, 0)
    out = cv2.GaussianBlur(out, (0, 0), float(rng.uniform(0.6, 1.8)))
    streaks = np.zeros((h, w), np.uint8)
    angle = rng.uniform(-0.4, 0.4)
    for _ in range(int(rng.integers(20, 120))):
        x, y = rng.uniform(0, w), rng.uniform(0, h)
        length = rng.uniform(0.03, 0.12) * h
        x2, y2 = x + length * math.sin(angle), y + length * math.cos(angle)
        cv2.line(streaks, (int(x), int(y)), (int(x2), int(y2)), int(rng.integers(40, 110)), 1, cv2.LINE_AA)
    streaks = cv2.GaussianBlur(streaks, (3, 3), 0)
    return cv2.add(out, cv2.merge([streaks, streaks, streaks]))
