"""The pilot networks: plain nn.Modules (export-friendly), (N, 3, H, W) HSV in [0, 1] -> (N, outputs).

- `PilotNet`: S3's network after NVIDIA's PilotNet, as published: 120x160 input, conv 24/36/48
  5x5 stride 2, conv 64/64 3x3, ELU, dropout 0.5, dense 100-50-10-1 -> steering.
- `SmallPilot`: ours, for one CPU thread: a 96x72 input, four strided convs with batch norm,
  one dense layer, and four outputs: one steering branch per desire (left, straight, right: the
  planner's chosen exit picks the branch, as in conditional imitation learning) and the
  teacher's target speed. Its activation is leaky ReLU (`act="leaky"`, slope 0.1, what
  training builds now) or ELU (`act="elu"`, the pilots trained before, whose checkpoints say
  nothing about it): on one thread ELU's exponential was the largest part of a training step
  (a batch of 128, channels-last: the ELUs 48 ms of an 84 ms forward pass, 31 ms of it on the
  first block's 128x16x36x48 activations), and a step with leaky ReLU takes about half the time
  (114 -> 61 ms).
"""
from __future__ import annotations

import torch
from torch import nn


def _flat_size(features: nn.Module, height: int, width: int) -> int:
    with torch.no_grad():
        return int(features(torch.zeros(1, 3, height, width)).numel())


class PilotNet(nn.Module):
    def __init__(self, height: int = 120, width: int = 160, dropout: float = 0.5):
        super().__init__()
        self.features = nn.Sequential(
            nn.Conv2d(3, 24, 5, 2), nn.ELU(), nn.Conv2d(24, 36, 5, 2), nn.ELU(), nn.Conv2d(36, 48, 5, 2), nn.ELU(),
            nn.Conv2d(48, 64, 3), nn.ELU(), nn.Conv2d(64, 64, 3), nn.ELU(), nn.Flatten())
        n = _flat_size(self.features, height, width)
        self.head = nn.Sequential(nn.Dropout(dropout), nn.Linear(n, 100), nn.ELU(), nn.Linear(100, 50), nn.ELU(),
                                  nn.Linear(50, 10), nn.ELU(), nn.Linear(10, 1))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.head(self.features(x))


ACTIVATIONS = ("leaky", "elu")


def _activation(act: str) -> nn.Module:
    if act not in ACTIVATIONS:
        raise ValueError(f"activation {act!r}: one of {', '.join(ACTIVATIONS)}")
    return nn.LeakyReLU(0.1) if act == "leaky" else nn.ELU()


def _cbe(cin: int, cout: int, k: int, stride: int, act: str) -> nn.Sequential:
    return nn.Sequential(nn.Conv2d(cin, cout, k, stride, k // 2, bias=False), nn.BatchNorm2d(cout), _activation(act))


class SmallPilot(nn.Module):
    """outputs: steering/left, steering/straight, steering/right, speed (m/s)."""

    def __init__(self, height: int = 72, width: int = 96, width_mult: int = 16, dropout: float = 0.3,
                 act: str = "elu"):
        super().__init__()
        w = width_mult
        self.features = nn.Sequential(_cbe(3, w, 5, 2, act), _cbe(w, int(1.5 * w), 3, 2, act),
                                      _cbe(int(1.5 * w), 2 * w, 3, 2, act), _cbe(2 * w, 3 * w, 3, 2, act), nn.Flatten())
        n = _flat_size(self.features, height, width)
        self.head = nn.Sequential(nn.Dropout(dropout), nn.Linear(n, 64), _activation(act), nn.Linear(64, 4))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.head(self.features(x))


def count_parameters(model: nn.Module) -> int:
    return sum(p.numel() for p in model.parameters())
