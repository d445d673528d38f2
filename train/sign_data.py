"""Sign-crop data for training: ImageFolder folders from `signlane gen signs` (or autolabel).

Class indices follow the VIA class order (not alphabetical folder order). Augmentation runs on
uint8 BGR crops with albumentations; then the runtime's own `preprocess_crops` makes the input,
so training sees exactly what the car's classifier will see.
"""
from __future__ import annotations

from pathlib import Path

import albumentations as A
import cv2
import lightning as L
import numpy as np
import torch
from torch.utils.data import DataLoader, Dataset

from signlane.onnx_model import InputSpec
from signlane.signs.classifier import DEFAULT_SPEC, preprocess_crops
from signlane.splits import VAL_FRACTION, split_of
from signlane.world.art import SIGN_CLASSES
from signlane_train.common import seed_worker

IMAGE_EXT = {".png", ".jpg", ".jpeg", ".bmp"}


def list_crops(roots: list[Path], classes: tuple[str, ...] = SIGN_CLASSES) -> list[tuple[Path, int]]:
    """(path, class index) for every crop under <root>/<class>/; unknown folders are an error."""
    items = []
    for root in roots:
        root = Path(root)
        if not root.is_dir():
            raise ValueError(f"{root}: not a folder of class folders")
        for d in sorted(p for p in root.iterdir() if p.is_dir()):
            if d.name not in classes:
                raise ValueError(f"{d}: folder name is not a class ({', '.join(classes)})")
            items += [(f, classes.index(d.name)) for f in sorted(d.iterdir()) if f.suffix.lower() in IMAGE_EXT]
    if not items:
        raise ValueError(f"no crops found under {', '.join(map(str, roots))}")
    return items


def crop_key(path: Path) -> str:
    """A crop's split key: `<class>/<file>` (the path train.txt / val.txt list)."""
    return f"{path.parent.name}/{path.name}"


def on_side(items: list[tuple[Path, int]], side: str, val_fraction: float = VAL_FRACTION) -> list[tuple[Path, int]]:
    """The (path, label) items on one side ('train' or 'val') of the shared split."""
    return [it for it in items if split_of(crop_key(it[0]), val_fraction) == side]


def train_augment(strength: float = 1.0, seed: int | None = None) -> A.Compose:
    """Appearance far beyond the renderer's: other cameras, printers, light and weather.
    No flips (left/right would swap) and small hue shifts (blue must stay blue, red red).
    `strength` (0..1) scales how often each change is applied (the generator's crops already
    carry blur, noise, exposure and occlusion of their own). `seed` makes the draws repeat
    (albumentations keeps its own generator, which the global seed does not reach)."""
    s = strength
    return A.Compose([
        A.Affine(scale=(0.8, 1.15), translate_percent=(-0.1, 0.1), rotate=(-12, 12), shear=(-8, 8), p=0.8 * s),
        A.Perspective(scale=(0.02, 0.1), p=0.4 * s),
        A.RandomBrightnessContrast(brightness_limit=0.35, contrast_limit=0.35, p=0.8 * s),
        A.RandomGamma(gamma_limit=(60, 160), p=0.4 * s),
        A.HueSaturationValue(hue_shift_limit=8, sat_shift_limit=40, val_shift_limit=30, p=0.6 * s),
        A.ToGray(p=0.03 * s),
        A.OneOf([A.MotionBlur(blur_limit=(3, 7)), A.GaussianBlur(sigma_limit=(0.3, 1.5))], p=0.35 * s),
        A.GaussNoise(std_range=(0.01, 0.08), p=0.35 * s),
        A.CoarseDropout(num_holes_range=(1, 2), hole_height_range=(0.1, 0.3), hole_width_range=(0.1, 0.3), p=0.2 * s),
        A.ImageCompression(quality_range=(20, 95), p=0.4 * s),
    ], seed=seed)


class CropDataset(Dataset):
    def __init__(self, items: list[tuple[Path, int]], spec: InputSpec, augment: A.Compose | None = None):
        self.items, self.spec, self.augment = items, spec, augment

    def __len__(self) -> int:
        return len(self.items)

    def __getitem__(self, i: int):
        path, label = self.items[i]
        img = cv2.imread(str(path), cv2.IMREAD_COLOR)
        if img is None:
            raise ValueError(f"{path}: unreadable crop")
        if self.augment is not None:
            img = self.augment(image=img)["image"]
        x = preprocess_crops([img], self.spec)[0]
        return torch.from_numpy(x), label


class SignDataModule(L.LightningDataModule):
    def __init__(self, roots: list[str | Path], batch_size: int = 128, val_fraction: float = VAL_FRACTION,
                 spec: InputSpec = DEFAULT_SPEC, workers: int = 0, augment: float = 1.0, seed: int = 0):
        super().__init__()
        self.augment, self.seed = augment, seed
        self.roots = [Path(r) for r in roots]
        self.batch_size, self.val_fraction, self.spec, self.workers = batch_size, val_fraction, spec, workers

    def setup(self, stage: str | None = None) -> None:
        items = list_crops(self.roots)
        self.train_items = on_side(items, "train", self.val_fraction)
        self.val_items = on_side(items, "val", self.val_fraction)
        if not self.train_items or not self.val_items:
            raise ValueError(f"need crops on both sides of the split; got {len(self.train_items)} train, "
                             f"{len(self.val_items)} val")

    def class_weights(self) -> torch.Tensor:
        """Square-root inverse-frequency weights for the cross-entropy: rare classes count more,
        but not so much that the many 'unknown' crops stop mattering (a non-sign taken for a sign
        is the costlier mistake on the car)."""
        counts = np.bincount([label for _, label in self.train_items], minlength=len(SIGN_CLASSES)).astype(float)
        w = np.sqrt(counts.sum() / np.maximum(counts, 1.0))
        return torch.tensor(w / w.mean(), dtype=torch.float32)

    def train_dataloader(self) -> DataLoader:
        return DataLoader(CropDataset(self.train_items, self.spec, train_augment(self.augment, self.seed)),
                          worker_init_fn=seed_worker, batch_size=self.batch_size, shuffle=True,
                          num_workers=self.workers, persistent_workers=self.workers > 0,
                          drop_last=len(self.train_items) > 2 * self.batch_size)

    def val_dataloader(self) -> DataLoader:
        return DataLoader(CropDataset(self.val_items, self.spec), batch_size=256, num_workers=self.workers,
                          persistent_workers=self.workers > 0)
