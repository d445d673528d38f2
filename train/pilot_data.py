"""Pilot training data: drive recordings (`signlane sim --record`, `signlane gen pilot`, `signlane
drive --record`: signlane/sim/drive_record.py), one item per recorded frame with the teacher's
steering as the label, the planner's desire and the teacher's target speed.

Augmentations that keep the label true to the picture (`steering_augment`):
- horizontal flip: the mirrored road bends the other way, so steering is negated and the desire
  left/right swapped;
- horizontal shift by dx pixels: for the far road, the view of a car turned by atan(dx / f)
  (f: the camera's focal length in pixels), so the label gains the steering that the teacher's
  pursuit gives for that heading error (`shift_gain` per radian);
- lateral move by d metres (`lateral_sample`): the road surface seen from a camera d metres to
  the side, a row-wise shift of the ground below the horizon (a flat-ground homography; the
  horizon and above stay), so the label gains the steering the teacher's pursuit gives for a car
  that far off its line (`lateral_gain` per metre). The rotation-only shift above cannot show a
  car that points along the lane but stands beside its centre: the view the pilot must learn to
  leave after a junction or a gust;
- small roll: the heading does not change, nor the label.
Light and colour changes (albumentations) never touch the label. Frames are decoded once, at
the net's input size (`cache_size`), and kept in memory (the input sizes are small).
"""
from __future__ import annotations

import math
import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import albumentations as A
import cv2
import lightning as L
import numpy as np
import torch
from torch.utils.data import DataLoader, Dataset, WeightedRandomSampler
from tqdm import tqdm

from signlane.camera import VIA_WHEELBASE_M
from signlane.config import CameraConfig, DriveConfig
from signlane.control import MAX_WHEEL_DEG, PurePursuit
from signlane.onnx_model import InputSpec
from signlane.pilot import DESIRES, SPLIT_BLOCK, PilotFrame, flip_desire, preprocess_frames, read_pilot_frames
from signlane.splits import VAL_FRACTION, split_of
from signlane_train.common import seed_worker

CACHE_SIZE = (160, 120)  # frames are kept at the input's size, at most this (the largest pilot input)
CAMERA = CameraConfig()  # the camera the recordings come from: VIA's, in both render styles
HFOV_DEG = CAMERA.hfov_deg


def pursuit_lateral_gain(lookahead_m: float = PurePursuit().lookahead_m(DriveConfig().cruise_speed),
                         wheelbase_m: float = VIA_WHEELBASE_M, max_wheel_deg: float = MAX_WHEEL_DEG) -> float:
    """Steering change per metre of the car standing right of its line, for the teacher's pure
    pursuit (signlane/control.py): kappa = 2 x / ld^2 with x = -d, steering = wheelbase * kappa
    / max wheel angle, linearised. The default lookahead is the pursuit's at cruise speed (7.5 m)
    with the camera's 1.1 m ahead of the axle left out: 0.16 per metre. Measured on the
    teacher itself (loop_demo's first straight, the car moved +-0.4 and 0.8 m at 5 m/s) it is
    0.11 per metre on painted roads and 0.23 in VIA's style (road-edges reads the kerbed
    carriageway's offset larger); one gain between them errs toward the centre on painted roads,
    where recovery is what the pilot lacks."""
    return 2.0 * wheelbase_m / (lookahead_m ** 2) / math.radians(max_wheel_deg)


def cache_size(spec: InputSpec) -> tuple[int, int]:
    """(w, h) the frames are kept and augmented at: the net's input size where it fits in
    CACHE_SIZE. Augmenting there instead of at CACHE_SIZE halves the loader's work a sample
    (0.73 -> 0.36 ms for the small pilot's 96x72, which has 2.8 times fewer pixels: the light
    changes, shadows, noise and JPEG scale with them), the larger part of a training step; the
    shifts and sideways moves are the same geometry at either size."""
    if spec.width <= CACHE_SIZE[0] and spec.height <= CACHE_SIZE[1]:
        return spec.width, spec.height
    return CACHE_SIZE


def load_frames(items: list[PilotFrame], size: tuple[int, int] = CACHE_SIZE, desc: str = "frames",
                threads: int | None = None) -> np.ndarray:
    """uint8 (N, h, w, 3) BGR frames at `size` (w, h), area-resized as the runtime shrinks them.
    Decoding is most of a large run's set-up (about 1.5 ms a 640x480 JPEG); OpenCV lets go of the
    GIL while it decodes and resizes, so a thread per core reads them side by side, each frame
    into its own row (the same array as one thread makes)."""
    out = np.empty((len(items), size[1], size[0], 3), np.uint8)

    def load(i: int) -> None:
        img = cv2.imread(str(items[i].image), cv2.IMREAD_COLOR)
        if img is None:
            raise ValueError(f"{items[i].image}: unreadable")
        out[i] = cv2.resize(img, size, interpolation=cv2.INTER_AREA)

    threads = threads or os.cpu_count() or 1
    with ThreadPoolExecutor(threads) as pool:
        # map in order; list() re-raises the first unreadable frame's error here
        list(tqdm(pool.map(load, range(len(items))), total=len(items), desc=desc, unit="frame",
                  leave=False, disable=len(items) < 200))
    return out


@dataclass(frozen=True)
class AugmentParams:
    flip: float = 0.5  # probability of a mirrored frame
    shift: float = 0.08  # max |dx| as a fraction of the width
    shift_p: float = 0.5
    shift_gain: float = 1.8  # steering per radian of heading error (VIA's car, pursuit at ~5 m)
    lateral_m: float = 0.6  # max |d| of the lateral move, metres
    lateral_p: float = 0.5
    lateral_gain: float = pursuit_lateral_gain()
    roll_deg: float = 2.0
    photometric: bool = True


STEERING_BIN = 0.05  # |steering| bin width of the balancing sampler
STEERING_BINS = 10  # the last bin holds every |steering| >= 0.45


def steering_weights(steering: np.ndarray, power: float) -> np.ndarray:
    """Sampling weight per frame: (frames in its |steering| bin) ** -power, mean 1. Straight road
    fills most of a drive, so uniform sampling shows the net few of the hard bends (S-bends, tight
    junction exits) its closed-loop failures come from; power 1 makes every bin equally likely,
    0 is uniform. |steering|, because a flip negates it."""
    s = np.abs(np.asarray(steering, np.float64))
    bins = np.minimum((s / STEERING_BIN).astype(int), STEERING_BINS - 1)
    counts = np.bincount(bins, minlength=STEERING_BINS).astype(np.float64)
    w = counts[bins] ** -float(power)
    return w / w.mean()


def flip_sample(image: np.ndarray, steering: float, desire: str) -> tuple[np.ndarray, float, str]:
    """A mirrored frame and its label: steering negated, left/right desire swapped."""
    return image[:, ::-1].copy(), -steering, flip_desire(desire)


def shift_sample(image: np.ndarray, steering: float, dx: float, gain: float,
                 hfov_deg: float = HFOV_DEG) -> tuple[np.ndarray, float]:
    """The frame moved dx pixels right (the road appears to the right: the car points left of
    it) and the label that steers back: + gain * atan(dx / f), clamped to [-1, 1]."""
    h, w = image.shape[:2]
    f = (w / 2) / math.tan(math.radians(hfov_deg) / 2)
    m = np.float32([[1, 0, dx], [0, 1, 0]])
    out = cv2.warpAffine(image, m, (w, h), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    return out, float(np.clip(steering + gain * math.atan(dx / f), -1.0, 1.0))


def lateral_sample(image: np.ndarray, steering: float, d_m: float, gain: float,
                   camera: CameraConfig = CAMERA) -> tuple[np.ndarray, float]:
    """The frame as seen from d_m metres to the right (the road moves left in view) and the label
    that steers back: steering - gain * d_m, clamped."""
    h, w = image.shape[:2]
    us, rows, per_m = _lateral_maps(w, h, camera)
    map_x = us + np.float32(d_m) * per_m  # output (u, v) reads input (u + move, v)
    out = cv2.remap(image, map_x, rows, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    return out, float(np.clip(steering - gain * d_m, -1.0, 1.0))


@lru_cache(maxsize=8)
def _lateral_maps(w: int, h: int, camera: CameraConfig) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(u, v, pixels moved per metre) maps for a (w, h) frame, read-only: a ground pixel moves by
    fx d (down . ray) / camera height, down . ray being the camera's horizon function (0 on the
    horizon, which stays put with everything above it). Made once per frame size: the loader
    calls this for every augmented frame."""
    cam = camera.camera(w, h)
    n, c = cam.horizon()
    us, vs = np.meshgrid(np.arange(w, dtype=np.float32), np.arange(h, dtype=np.float32))
    depth = np.maximum(0.0, n[0] * us + n[1] * vs + c)
    per_m = (cam.K[0, 0] / camera.height_m * depth).astype(np.float32)
    for a in (us, vs, per_m):
        a.flags.writeable = False
    return us, vs, per_m


def roll_sample(image: np.ndarray, deg: float) -> np.ndarray:
    h, w = image.shape[:2]
    m = cv2.getRotationMatrix2D((w / 2, h / 2), deg, 1.0)
    return cv2.warpAffine(image, m, (w, h), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)


def photometric(seed: int | None = None) -> A.Compose:
    """Light, colour and sensor changes: labels unchanged."""
    return A.Compose([
        A.RandomBrightnessContrast(brightness_limit=0.3, contrast_limit=0.3, p=0.7),
        A.HueSaturationValue(hue_shift_limit=12, sat_shift_limit=30, val_shift_limit=20, p=0.5),
        A.RandomShadow(shadow_roi=(0, 0.4, 1, 1), num_shadows_limit=(1, 2), p=0.2),
        A.GaussNoise(std_range=(0.01, 0.05), p=0.3),
        A.ImageCompression(quality_range=(40, 95), p=0.3),
    ], seed=seed)


def steering_augment(image: np.ndarray, steering: float, desire: str, rng, p: AugmentParams) -> tuple[np.ndarray, float, str]:
    """One draw of the geometric augmentations with the label each implies; rng: anything with
    numpy's random() and uniform() (a Generator, or the np.random module)."""
    if rng.random() < p.flip:
        image, steering, desire = flip_sample(image, steering, desire)
    if p.shift > 0 and rng.random() < p.shift_p:
        image, steering = shift_sample(image, steering, float(rng.uniform(-p.shift, p.shift)) * image.shape[1],
                                       p.shift_gain)
    if p.lateral_m > 0 and rng.random() < p.lateral_p:
        image, steering = lateral_sample(image, steering, float(rng.uniform(-p.lateral_m, p.lateral_m)),
                                         p.lateral_gain)
    if p.roll_deg > 0:
        image = roll_sample(image, float(rng.uniform(-p.roll_deg, p.roll_deg)))
    return image, steering, desire


class PilotDataset(Dataset):
    """(input float32 (3, h, w), steering, desire index, speed) per frame."""

    def __init__(self, items: list[PilotFrame], frames: np.ndarray, spec: InputSpec,
                 augment: AugmentParams | None = None, seed: int = 0):
        self.items, self.frames, self.spec, self.params = items, frames, spec, augment
        self.augment = photometric(seed) if augment is not None and augment.photometric else None

    def __len__(self) -> int:
        return len(self.items)

    def __getitem__(self, i: int):
        it = self.items[i]
        img, steering, desire = self.frames[i], it.steering, it.desire
        if self.params is not None:
            # numpy's global generator: seeded by seed_everything, and per loader worker by seed_worker
            img, steering, desire = steering_augment(img, steering, desire, np.random, self.params)
            if self.augment is not None:
                img = self.augment(image=np.ascontiguousarray(img))["image"]
        x = preprocess_frames([np.ascontiguousarray(img)], self.spec)[0]
        return (torch.from_numpy(x), torch.tensor(steering, dtype=torch.float32),
                torch.tensor(DESIRES.index(desire)), torch.tensor(it.speed, dtype=torch.float32))


class PilotDataModule(L.LightningDataModule):
    def __init__(self, roots: list[str | Path], spec: InputSpec, batch_size: int = 100,
                 val_fraction: float = VAL_FRACTION, augment: AugmentParams | None = AugmentParams(),
                 workers: int = 0, seed: int = 0, balance: float = 0.0):
        super().__init__()
        self.roots = [Path(r) for r in roots]
        self.balance = balance
        self.spec, self.batch_size, self.val_fraction = spec, batch_size, val_fraction
        self.augment, self.workers, self.seed = augment, workers, seed
        self.train_items: list[PilotFrame] = []

    def setup(self, stage: str | None = None) -> None:
        if self.train_items:
            return
        items = read_pilot_frames(self.roots)
        train = [i for i, it in enumerate(items) if split_of(it.key, self.val_fraction) == "train"]
        val = [i for i, it in enumerate(items) if split_of(it.key, self.val_fraction) == "val"]
        if not train or not val:
            raise ValueError(f"need frames on both sides of the split; got {len(train)} train, {len(val)} val "
                             f"(blocks of {SPLIT_BLOCK} frames per side: record more)")
        frames = load_frames(items, cache_size(self.spec))
        self.train_items, self.val_items = [items[i] for i in train], [items[i] for i in val]
        self.train_frames, self.val_frames = frames[train], frames[val]

    def train_dataloader(self) -> DataLoader:
        ds = PilotDataset(self.train_items, self.train_frames, self.spec, self.augment, self.seed)
        sampler = None
        if self.balance > 0:  # as many draws per epoch as frames, weighted toward rare steering
            w = steering_weights(np.array([it.steering for it in self.train_items]), self.balance)
            sampler = WeightedRandomSampler(torch.from_numpy(w), len(ds), replacement=True,
                                            generator=torch.Generator().manual_seed(self.seed))
        return DataLoader(ds, batch_size=self.batch_size, shuffle=sampler is None, sampler=sampler,
                          num_workers=self.workers,
                          worker_init_fn=seed_worker, persistent_workers=self.workers > 0,
                          drop_last=len(ds) > 2 * self.batch_size)

    def val_dataloader(self) -> DataLoader:
        return DataLoader(PilotDataset(self.val_items, self.val_frames, self.spec), batch_size=256,
                          num_workers=0)
