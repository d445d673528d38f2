"""LightningModule for the pilot: MSE on the teacher's steering (on the desire's branch for our
branched net, plus the teacher's target speed), steering MAE/RMSE on the val split, and a
predicted-vs-teacher steering chart after every validation epoch."""
from __future__ import annotations

from pathlib import Path

import lightning as L
import torch
import torch.nn.functional as F

from signlane_train.common import as_channels_last, channels_last, one_cycle
from signlane_train.pilot_net import PilotNet, SmallPilot

ARCHS = ("pilotnet", "small")
SCHEDULES = ("constant", "onecycle")
SPEED_SCALE = 5.0  # m/s: the speed loss is on speed / this (steering is within [-1, 1])


def pick_steering(out: torch.Tensor, desire: torch.Tensor) -> torch.Tensor:
    """(N, outputs) -> (N,) steering: the desire's branch (columns 0..2) for a branched output,
    else the single column."""
    if out.shape[1] == 1:
        return out[:, 0]
    return out[:, :3].gather(1, desire.view(-1, 1)).squeeze(1)


class PilotTask(L.LightningModule):
    def __init__(self, arch: str = "pilotnet", lr: float = 1e-4, weight_decay: float = 0.0, speed_weight: float = 0.1,
                 input_size: tuple[int, int] = (160, 120), width: int = 16, schedule: str = "constant",
                 act: str = "elu"):
        # act: small's activation. "elu" is the default here for the checkpoints saved before the
        # choice existed (their hyperparameters do not name it); train_pilot asks for "leaky"
        super().__init__()
        if arch not in ARCHS:
            raise ValueError(f"arch {arch!r}: one of {', '.join(ARCHS)}")
        if schedule not in SCHEDULES:
            raise ValueError(f"schedule {schedule!r}: one of {', '.join(SCHEDULES)}")
        self.save_hyperparameters()
        w, h = input_size
        self.net = channels_last(PilotNet(h, w) if arch == "pilotnet" else SmallPilot(h, w, width, act=act))
        self.samples_dir: Path | None = None
        self._val: list[tuple[torch.Tensor, torch.Tensor]] = []

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.net(as_channels_last(x))

    def _loss(self, out, steering, desire, speed) -> tuple[torch.Tensor, torch.Tensor]:
        pred = pick_steering(out, desire)
        loss = F.mse_loss(pred, steering)
        if out.shape[1] == 4:
            loss = loss + self.hparams.speed_weight * F.mse_loss(out[:, 3] / SPEED_SCALE, speed / SPEED_SCALE)
        return loss, pred

    def training_step(self, batch, _):
        x, steering, desire, speed = batch
        loss, pred = self._loss(self(x), steering, desire, speed)
        self.log("train/loss", loss, prog_bar=True)
        self.log("train/mae", (pred - steering).abs().mean(), on_epoch=True, on_step=False)
        return loss

    def validation_step(self, batch, _):
        x, steering, desire, speed = batch
        out = self(x)
        loss, pred = self._loss(out, steering, desire, speed)
        self.log("val/loss", loss, prog_bar=True)
        self._val.append((pred.detach().cpu(), steering.cpu()))
        if out.shape[1] == 4:
            self.log("val/speed_mae", (out[:, 3] - speed).abs().mean())

    def on_validation_epoch_end(self) -> None:
        if not self._val:
            return
        pred = torch.cat([p for p, _ in self._val])
        truth = torch.cat([t for _, t in self._val])
        self._val.clear()
        err = pred - truth
        self.log("val/mae", err.abs().mean(), prog_bar=True)
        self.log("val/rmse", err.pow(2).mean().sqrt())
        if self.samples_dir is not None and not self.trainer.sanity_checking:
            self._write_chart(pred.numpy(), truth.numpy())

    def _write_chart(self, pred, truth) -> None:
        """samples/epoch_<k>.png: predicted and teacher steering over the val frames in order."""
        from signlane.draw import write_image
        from signlane.plots import steering_chart
        write_image(self.samples_dir / f"epoch_{self.current_epoch:03d}.png",
                    steering_chart(truth[:600], {f"epoch {self.current_epoch}": pred[:600]},
                                   "val frames (the first 600, in order)"))

    def configure_optimizers(self):
        # S3: Adam, lr 1e-4, constant (ours the same optimiser with a higher peak rate, which its
        # batch norm takes, on a one-cycle schedule like the lane and sign nets)
        opt = torch.optim.Adam(self.parameters(), lr=self.hparams.lr, weight_decay=self.hparams.weight_decay)
        if self.hparams.schedule == "onecycle":
            return one_cycle(self, opt, self.hparams.lr, pct_start=0.2)
        return opt
