"""Lane-segmentation data for training: lane dataset folders (`signlane gen lanes`, `signlane
autolabel lanes`, or any folder of images/ + masks/<stem>.png made by hand), mixed freely.

Masks are read as class ids 0/1/255 (signlane.label_masks: the folder's manifest says
`"mask_encoding"`; sets made before the key, and folders made by hand without a manifest, are
binary 0/255 and give the same ids). Albumentations run jointly on the uint8 BGR frame and its
ids at the frame's size (the border an affine or perspective warp pads in is 255: no label);
then the runtime's own `preprocess_frames` makes the input and `mask_target` the target (0, 1,
255 = ignored by the loss and the metrics), so training sees exactly what the car's model will see.
A frame with a road-surface mask (`drivable/<id>.png`: gen lanes --drivable, autolabel lanes)
also gives a drivable target (`drivable_target`); a frame without one gives 255 (no label)
there, so sets with and without road masks mix.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import albumentations as A
import cv2
import lightning as L
import numpy as np
import torch
from torch.utils.data import DataLoader, Dataset

from signlane.label_masks import BINARY, IGNORE, dataset_encoding, read_mask
from signlane.lanes.seg_model import DEFAULT_SPEC, mask_target, preprocess_frames
from signlane.onnx_model import InputSpec
from signlane.splits import VAL_FRACTION, split_of
from signlane_train.common import seed_worker

IMAGE_EXT = (".jpg", ".jpeg", ".png", ".bmp")


@dataclass(frozen=True)
class Item:
    image: Path
    mask: Path
    key: str  # stable name for the train/val split
    encoding: str = BINARY  # of the mask file (signlane.label_masks), from its folder's manifest
    drivable: Path | None = None  # the road-surface mask (ids 0/1/255), where the set has one


def list_frames(roots: list[Path]) -> list[Item]:
    """(image, mask) pairs of every folder: from labels.jsonl when present, else images/<stem>.*
    paired with masks/<stem>.png. A folder with neither, or with no frames (an autolabel run that
    kept none), is an error: mixing in an empty set silently would train on less than asked.
    Each item carries its folder's mask encoding (ValueError for one this version does not read)."""
    items: list[Item] = []
    for root in map(Path, roots):
        labels = root / "labels.jsonl"
        enc = dataset_encoding(root)
        if labels.is_file():
            found = [json.loads(line) for line in labels.read_text().splitlines() if line.strip()]
            own = [Item(root / rec["image"], root / rec["mask"], f"{root.name}/{rec['id']}", enc,
                        root / rec["drivable"] if rec.get("drivable") else None) for rec in found]
            why = "labels.jsonl lists no frames"
        elif (root / "images").is_dir() and (root / "masks").is_dir():
            own = [Item(img, root / "masks" / f"{img.stem}.png", f"{root.name}/{img.stem}", enc,
                        _drivable_file(root, img.stem))
                   for img in sorted((root / "images").iterdir())
                   if img.suffix.lower() in IMAGE_EXT and (root / "masks" / f"{img.stem}.png").is_file()]
            why = "no images/<stem> has a masks/<stem>.png"
        else:
            raise ValueError(f"{root}: not a lane dataset (needs labels.jsonl, or images/ and masks/)")
        if not own:
            raise ValueError(f"{root}: an empty training set ({why}); leave it out or fill it")
        items += own
    return items


def _drivable_file(root: Path, stem: str) -> Path | None:
    f = root / "drivable" / f"{stem}.png"
    return f if f.is_file() else None


def train_augment(seed: int | None = None) -> A.Compose:
    """Other cameras (mirror, roll, zoom, shift, perspective), light, weather and sensors beyond
    the renderer's, applied to frame and mask ids together (the ids by nearest neighbour; what a
    warp pads in is 255, no label); `seed` makes the draws repeat (albumentations keeps its own
    generator)."""
    return A.Compose([
        A.HorizontalFlip(p=0.5),  # a mirrored road is still a road: paint stays paint
        A.Affine(scale=(0.85, 1.15), translate_percent=(-0.06, 0.06), rotate=(-6, 6), fill_mask=IGNORE, p=0.6),
        A.Perspective(scale=(0.02, 0.06), fill_mask=IGNORE, p=0.3),
        A.RandomBrightnessContrast(brightness_limit=0.35, contrast_limit=0.4, p=0.8),
        A.RandomGamma(gamma_limit=(55, 170), p=0.4),
        A.HueSaturationValue(hue_shift_limit=15, sat_shift_limit=40, val_shift_limit=25, p=0.6),
        A.ToGray(p=0.08),
        A.RandomShadow(shadow_roi=(0, 0.4, 1, 1), num_shadows_limit=(1, 3), p=0.25),
        A.OneOf([A.MotionBlur(blur_limit=(3, 7)), A.GaussianBlur(sigma_limit=(0.3, 1.5))], p=0.3),
        A.GaussNoise(std_range=(0.01, 0.08), p=0.35),
        A.ImageCompression(quality_range=(20, 95), p=0.4),
    ], seed=seed, additional_targets={"drivable": "mask"})


def read_pair(item: Item) -> tuple[np.ndarray, np.ndarray]:
    """uint8 (H, W, 3) BGR frame and its uint8 (H, W) mask ids 0/1/255, whatever the encoding."""
    img = cv2.imread(str(item.image), cv2.IMREAD_COLOR)
    if img is None:
        raise ValueError(f"{item.image}: unreadable")
    mask = read_mask(item.mask, item.encoding)
    if mask.shape != img.shape[:2]:
        raise ValueError(f"{item.mask}: mask {mask.shape} is not the image's size {img.shape[:2]}")
    return img, mask


def read_drivable(item: Item, shape: tuple[int, int]) -> np.ndarray:
    """uint8 (H, W) road ids 0/1/255 of a frame: all 255 (no label) without a drivable mask."""
    if item.drivable is None:
        return np.full(shape, IGNORE, np.uint8)
    road = read_mask(item.drivable, item.encoding)
    if road.shape != shape:
        raise ValueError(f"{item.drivable}: mask {road.shape} is not the image's size {shape}")
    return road


def drivable_target(road: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """Road ids (H, W) 0/1/255 at the frame's size -> uint8 (h, w) target at the model's output
    size (w, h): the majority of each cell's labelled pixels (a surface, not a thin line), 255
    where most of the cell has no label."""
    labelled = (road != IGNORE).astype(np.float32)
    on = cv2.resize((road == 1).astype(np.float32), size, interpolation=cv2.INTER_AREA)
    known = cv2.resize(labelled, size, interpolation=cv2.INTER_AREA)
    target = (on >= 0.5 * np.maximum(known, 1e-6)).astype(np.uint8)
    target[known < 0.5] = IGNORE
    return target


class FrameDataset(Dataset):
    """(input, marking target, drivable target) per frame; with drivable=False only the first
    two (a marking model)."""

    def __init__(self, items: list[Item], spec: InputSpec, augment: A.Compose | None = None, drivable: bool = False):
        self.items, self.spec, self.augment, self.drivable = items, spec, augment, drivable

    def __len__(self) -> int:
        return len(self.items)

    def __getitem__(self, i: int):
        img, mask = read_pair(self.items[i])
        road = read_drivable(self.items[i], mask.shape) if self.drivable else None
        if self.augment is not None:
            out = self.augment(image=img, mask=mask, drivable=road if road is not None else mask)
            img, mask, road = out["image"], out["mask"], out["drivable"] if road is not None else None
        size = (self.spec.width, self.spec.height)
        x = torch.from_numpy(preprocess_frames([img], self.spec)[0])
        y = torch.from_numpy(mask_target(mask == 1, size, ignore=mask == IGNORE).astype(np.int64))
        if road is None:
            return x, y
        return x, y, torch.from_numpy(drivable_target(road, size).astype(np.int64))


class LaneDataModule(L.LightningDataModule):
    def __init__(self, roots: list[str | Path], batch_size: int = 32, val_fraction: float = VAL_FRACTION,
                 spec: InputSpec = DEFAULT_SPEC, workers: int = 0, seed: int = 0):
        super().__init__()
        self.drivable = False  # set by setup: some frame has a road-surface mask (a road model is trained)
        self.seed = seed
        self.roots = [Path(r) for r in roots]
        self.batch_size, self.val_fraction, self.spec, self.workers = batch_size, val_fraction, spec, workers

    def setup(self, stage: str | None = None) -> None:
        items = list_frames(self.roots)
        self.train_items = [it for it in items if split_of(it.key, self.val_fraction) == "train"]
        self.val_items = [it for it in items if split_of(it.key, self.val_fraction) == "val"]
        self.drivable = any(it.drivable is not None for it in items)
        if not self.train_items or not self.val_items:
            raise ValueError(f"need frames on both sides of the split; got {len(self.train_items)} train, "
                             f"{len(self.val_items)} val")

    def train_dataloader(self) -> DataLoader:
        return DataLoader(FrameDataset(self.train_items, self.spec, train_augment(self.seed), self.drivable),
                          worker_init_fn=seed_worker, batch_size=self.batch_size, shuffle=True, num_workers=self.workers,
                          persistent_workers=self.workers > 0,
                          drop_last=len(self.train_items) > 2 * self.batch_size)

    def val_dataloader(self) -> DataLoader:
        return DataLoader(FrameDataset(self.val_items, self.spec, drivable=self.drivable), batch_size=64, num_workers=self.workers,
                          persistent_workers=self.workers > 0)
