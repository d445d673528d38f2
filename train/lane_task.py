"""LightningModule for lane segmentation: weighted cross-entropy + soft Dice (thin structures:
paint is a few percent of the pixels, so plain CE would settle for 'all road'), marking IoU and
F1, and a picture of sample predictions after every validation epoch. Target pixels of 255 have
no label (signlane.label_masks.IGNORE): the losses and the metrics leave them out.

With drivable=True the net is a road model (signlane.lanes.seg_model.ROAD_CLASSES): logits
channels 0-1 are the marking head, 2-3 the road-surface head, trained with plain cross-entropy on
the drivable targets (a surface: no class weighting needed), plus `drivable_dice` x its soft Dice
(the overlap the drivable IoU scores), and scored by val/drivable_iou."""
from __future__ import annotations

from pathlib import Path

import lightning as L
import numpy as np
import torch
import torch.nn.functional as F
from torchmetrics.classification import BinaryF1Score, BinaryJaccardIndex

from signlane.label_masks import IGNORE
from signlane_train.common import as_channels_last, channels_last, one_cycle
from signlane_train.lane_net import LaneSegNet


def dice_loss(logits: torch.Tensor, target: torch.Tensor, eps: float = 1.0) -> torch.Tensor:
    """1 - soft Dice of class 1 (marking, or road surface) over the batch's labelled pixels
    (target 0 or 1; 255 ignored). With no labelled pixel it is 0, without a gradient."""
    p = torch.softmax(logits, 1)[:, 1] * (target != IGNORE)
    t = (target == 1).float()
    inter = (p * t).sum()
    return 1.0 - (2 * inter + eps) / (p.sum() + t.sum() + eps)


def weighted_ce(logits: torch.Tensor, target: torch.Tensor, weight: torch.Tensor) -> torch.Tensor:
    """Class-weighted cross-entropy, the mean over the labelled pixels (what F.cross_entropy's
    mean is, weights included); pixels of 255 are left out, and a batch with none labelled gives
    0 (F.cross_entropy's mean would be 0/0)."""
    total = F.cross_entropy(logits, target, weight=weight, ignore_index=IGNORE, reduction="sum")
    labelled = weight[target.clamp(max=len(weight) - 1)] * (target != IGNORE)
    return total / labelled.sum().clamp_min(1e-12)


class LaneTask(L.LightningModule):
    def __init__(self, width: int = 16, lr: float = 4e-3, weight_decay: float = 1e-4, pos_weight: float = 4.0,
                 dice_weight: float = 1.0, input_size: tuple[int, int] = (160, 120), drivable: bool = False,
                 drivable_weight: float = 0.5, scene: bool = False, drivable_dice: float = 0.0):
        super().__init__()
        self.save_hyperparameters()
        self.net = channels_last(LaneSegNet(4 if drivable else 2, width, scene))
        self.val_road_iou = BinaryJaccardIndex(ignore_index=IGNORE)
        self.register_buffer("ce_weight", torch.tensor([1.0, pos_weight]), persistent=False)
        self.val_iou, self.val_f1 = BinaryJaccardIndex(ignore_index=IGNORE), BinaryF1Score(ignore_index=IGNORE)
        self.train_iou = BinaryJaccardIndex(ignore_index=IGNORE)
        self.samples_dir: Path | None = None  # set by the trainer script: sample_<epoch>.png go there
        self.sample_batch: tuple[torch.Tensor, torch.Tensor] | None = None

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.net(as_channels_last(x))

    def _loss(self, logits: torch.Tensor, y: torch.Tensor, road: torch.Tensor | None = None) -> torch.Tensor:
        mark = logits[:, :2]
        loss = weighted_ce(mark, y, self.ce_weight) + self.hparams.dice_weight * dice_loss(mark, y)
        if road is not None:
            surface = logits[:, 2:4]
            loss = loss + self.hparams.drivable_weight * weighted_ce(surface, road, self.ce_weight.new_ones(2))
            if self.hparams.drivable_dice:  # the score is IoU: a surface's overlap, not its pixels' mean
                loss = loss + self.hparams.drivable_dice * dice_loss(surface, road)
        return loss

    @staticmethod
    def _unpack(batch):
        return (batch[0], batch[1], batch[2]) if len(batch) == 3 else (batch[0], batch[1], None)

    def training_step(self, batch, _):
        x, y, road = self._unpack(batch)
        logits = self(x)
        loss = self._loss(logits, y, road)
        self.train_iou(logits[:, :2].argmax(1), y)
        self.log("train/loss", loss, prog_bar=True)
        self.log("train/iou", self.train_iou, on_epoch=True, on_step=False)
        return loss

    def validation_step(self, batch, _):
        x, y, road = self._unpack(batch)
        logits = self(x)
        self.log("val/loss", self._loss(logits, y, road), prog_bar=True)
        pred = logits[:, :2].argmax(1)
        self.val_iou.update(pred, y)
        self.val_f1.update(pred, y)
        if road is not None:
            self.val_road_iou.update(logits[:, 2:4].argmax(1), road)

    def on_validation_epoch_end(self) -> None:
        self.log("val/iou", self.val_iou.compute(), prog_bar=True)
        self.log("val/f1", self.val_f1.compute())
        self.val_iou.reset()
        self.val_f1.reset()
        if self.hparams.drivable:
            self.log("val/drivable_iou", self.val_road_iou.compute(), prog_bar=True)
            self.val_road_iou.reset()
        if self.samples_dir is not None and self.sample_batch is not None and not self.trainer.sanity_checking:
            self._write_samples()

    def _write_samples(self) -> None:
        """samples/epoch_<k>.png: inputs with truth (green) and prediction (red; yellow = both);
        pixels without a label darkened."""
        from signlane.draw import contact_sheet, write_image
        from signlane.lanes.seg_model import DEFAULT_SPEC as spec
        x, y = self.sample_batch[:2]
        with torch.no_grad():
            pred = self(x.to(self.device))[:, :2].argmax(1).cpu().numpy()
        tiles = []
        for xi, yi, pi in zip(x.numpy(), y.numpy(), pred):
            rgb = (xi.transpose(1, 2, 0) * np.array(spec.std) + np.array(spec.mean)) / spec.scale
            img = np.clip(rgb, 0, 255).astype(np.uint8)[:, :, ::-1].copy()
            img[yi == 1] = (0.5 * img[yi == 1] + [0, 127, 0]).astype(np.uint8)
            img[pi > 0] = (0.5 * img[pi > 0] + [0, 0, 127]).astype(np.uint8)
            img[yi == IGNORE] //= 3
            tiles.append(img)
        write_image(self.samples_dir / f"epoch_{self.current_epoch:03d}.png", contact_sheet(tiles, cols=4))

    def configure_optimizers(self):
        opt = torch.optim.AdamW(self.parameters(), lr=self.hparams.lr, weight_decay=self.hparams.weight_decay)
        return one_cycle(self, opt, self.hparams.lr, pct_start=0.15)
