"""The lane-marking segmentation network: a plain nn.Module (export-friendly) sized for one CPU
thread. A strided stem and depthwise-separable stages go down to 1/8 for context (dashes,
shadows, worn paint need a wide view); a light decoder with skips comes back to 1/2 of the
input, where a pixel shuffle makes the logits at the input's full size (each 1/2 cell predicts
its 2x2 pixels: thin far lines keep their position at a quarter of the cost of a 1/1 decoder)."""
from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn


def _cbr(cin: int, cout: int, k: int = 1, stride: int = 1, groups: int = 1, dilation: int = 1) -> nn.Sequential:
    pad = dilation * (k // 2)
    return nn.Sequential(nn.Conv2d(cin, cout, k, stride, pad, dilation=dilation, groups=groups, bias=False),
                         nn.BatchNorm2d(cout), nn.ReLU(inplace=True))


class SepBlock(nn.Module):
    """Depthwise 3x3 + pointwise 1x1; residual when the shape is kept."""

    def __init__(self, cin: int, cout: int, stride: int = 1, dilation: int = 1):
        super().__init__()
        self.dw = _cbr(cin, cin, 3, stride, groups=cin, dilation=dilation)
        self.pw = nn.Sequential(nn.Conv2d(cin, cout, 1, bias=False), nn.BatchNorm2d(cout))
        self.residual = stride == 1 and cin == cout

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        y = self.pw(self.dw(x))
        return F.relu(y + x if self.residual else y)


class ImageContrast(nn.Module):
    """The frame beside itself normalised by its own per-channel mean and spread: (N, 3, H, W) ->
    (N, 6, H, W). A night, fog or glare frame and a random look's odd colours then reach the stem
    at a daylight frame's contrast, while the raw channels keep what absolute brightness says
    (white paint is bright). `eps` (input units: the runtime's inputs span about 4) keeps a flat
    frame's noise from being blown up."""

    def __init__(self, eps: float = 0.05):
        super().__init__()
        self.eps = eps

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        centred = x - x.mean(dim=(2, 3), keepdim=True)
        spread = (centred * centred).mean(dim=(2, 3), keepdim=True).add(self.eps ** 2).sqrt()
        return torch.cat([x, centred / spread], 1)


class SceneContext(nn.Module):
    """The whole frame's average of the deepest features, mixed by a 1x1 conv and added back
    everywhere: what this frame's road and verge look like (a random look's road may be the
    colour another look gives its grass) reaches every pixel, not only a dilated neighbourhood."""

    def __init__(self, channels: int):
        super().__init__()
        self.mix = nn.Sequential(nn.Conv2d(channels, channels, 1), nn.ReLU(inplace=True))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return x + self.mix(x.mean(dim=(2, 3), keepdim=True))


class LaneSegNet(nn.Module):
    """3 x H x W (H, W multiples of 8) -> class logits (N, classes, H, W). `scene` adds the
    frame-wide inputs and features (ImageContrast before the stem, SceneContext at 1/8): nets
    trained before it have neither, and load with scene=False."""

    def __init__(self, classes: int = 2, width: int = 16, scene: bool = False):
        super().__init__()
        w = width
        self.contrast = ImageContrast() if scene else nn.Identity()
        self.stem = _cbr(6 if scene else 3, w, 3, 2)  # 1/2
        self.down1 = nn.Sequential(SepBlock(w, 2 * w, 2), SepBlock(2 * w, 2 * w))  # 1/4
        self.down2 = nn.Sequential(SepBlock(2 * w, 4 * w, 2), SepBlock(4 * w, 4 * w, dilation=2),
                                   SepBlock(4 * w, 4 * w, dilation=4))  # 1/8, wide receptive field
        self.context = SceneContext(4 * w) if scene else nn.Identity()
        self.lat2 = _cbr(4 * w, 2 * w)
        self.fuse1 = SepBlock(2 * w, 2 * w)
        self.lat1 = _cbr(2 * w, w)
        self.fuse0 = SepBlock(w, w)
        self.head = nn.Sequential(nn.Conv2d(w, 4 * classes, 1), nn.PixelShuffle(2))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        s0 = self.stem(self.contrast(x))
        s1 = self.down1(s0)
        s2 = self.context(self.down2(s1))
        # channels are reduced before upsampling: the 1x1 convs then run on 4x fewer pixels
        d1 = self.fuse1(F.interpolate(self.lat2(s2), scale_factor=2.0, mode="nearest") + s1)
        d0 = self.fuse0(F.interpolate(self.lat1(d1), scale_factor=2.0, mode="nearest") + s0)
        return self.head(d0)


def count_parameters(model: nn.Module) -> int:
    return sum(p.numel() for p in model.parameters())
