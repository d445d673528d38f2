"""LightningModule for the sign classifier: weighted cross-entropy, accuracy, macro-F1, per-class recall."""
from __future__ import annotations

import lightning as L
import torch
from torch import nn
from torchmetrics.classification import MulticlassAccuracy, MulticlassConfusionMatrix, MulticlassF1Score, MulticlassRecall

from signlane.world.art import SIGN_CLASSES
from signlane_train.common import as_channels_last, channels_last, one_cycle
from signlane_train.sign_net import SignNet


class SignTask(L.LightningModule):
    def __init__(self, size: int = 32, lr: float = 3e-3, weight_decay: float = 1e-4, epochs: int = 20,
                 class_weights: list[float] | None = None, width: int = 16):
        super().__init__()
        self.save_hyperparameters()
        n = len(SIGN_CLASSES)
        self.net = channels_last(SignNet(n, size, width))
        w = torch.tensor(class_weights, dtype=torch.float32) if class_weights else None
        self.loss = nn.CrossEntropyLoss(weight=w, label_smoothing=0.05)
        self.val_acc = MulticlassAccuracy(n, average="micro")
        self.val_f1 = MulticlassF1Score(n, average="macro")
        self.val_recall = MulticlassRecall(n, average=None)
        self.val_confusion = MulticlassConfusionMatrix(n)
        self.train_acc = MulticlassAccuracy(n, average="micro")

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.net(x)

    def training_step(self, batch, _):
        x, y = batch
        x = as_channels_last(x)
        logits = self(x)
        loss = self.loss(logits, y)
        self.train_acc(logits, y)
        self.log("train/loss", loss, prog_bar=True)
        self.log("train/acc", self.train_acc, on_epoch=True, on_step=False)
        return loss

    def validation_step(self, batch, _):
        x, y = batch
        x = as_channels_last(x)
        logits = self(x)
        self.log("val/loss", self.loss(logits, y), prog_bar=True)
        for m in (self.val_acc, self.val_f1, self.val_recall, self.val_confusion):
            m.update(logits, y)

    def on_validation_epoch_end(self) -> None:
        self.log("val/acc", self.val_acc.compute(), prog_bar=True)
        self.log("val/f1", self.val_f1.compute())
        for name, r in zip(SIGN_CLASSES, self.val_recall.compute()):
            self.log(f"val/recall_{name}", r)
            if name == "unknown":  # the costly mistake on the car: a non-sign taken for a sign
                self.log("val/non_sign_accepted", 1.0 - r)
        self.confusion = self.val_confusion.compute().cpu()
        for m in (self.val_acc, self.val_f1, self.val_recall, self.val_confusion):
            m.reset()

    def configure_optimizers(self):
        opt = torch.optim.AdamW(self.parameters(), lr=self.hparams.lr, weight_decay=self.hparams.weight_decay)
        return one_cycle(self, opt, self.hparams.lr, pct_start=0.2)
