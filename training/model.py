"""The CenterNet-style vehicle net in plain torch (no torchvision).

Backbone: five stride-2 3x3 convs (+ BN + ReLU, more convs at strides 8-32); an
FPN-like top-down path fuses strides 32 -> 16 -> 8 -> 4; one shared 3x3 conv and two
1x1 outputs at stride 4 (kept thin: the stride-4 layers dominate the cost):

* ``heatmap`` (1 channel, sigmoid): vehicle-centre probability;
* ``ltrb`` (4 channels): distances in input pixels from the cell centre to the
  box's left, top, right, bottom edges (``stride * raw``).

Only Conv, BatchNorm (folded at export), ReLU, Add, Resize(nearest), Sigmoid, Mul:
exports cleanly to ONNX opset 17.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn


def cbr(cin: int, cout: int, stride: int = 1, k: int = 3) -> nn.Sequential:
    return nn.Sequential(nn.Conv2d(cin, cout, k, stride, k // 2, bias=False), nn.BatchNorm2d(cout), nn.ReLU(inplace=True))


class CenterNetVehicle(nn.Module):
    def __init__(self, width: tuple[int, ...] = (16, 32, 48, 64, 96), neck: int = 32, head: int = 24,
                 stride: int = 4) -> None:
        super().__init__()
        c1, c2, c3, c4, c5 = width
        self.stride = stride
        self.s4 = nn.Sequential(cbr(3, c1, 2), cbr(c1, c2, 2))                 # /4
        self.s8 = nn.Sequential(cbr(c2, c3, 2), cbr(c3, c3))                   # /8
        self.s16 = nn.Sequential(cbr(c3, c4, 2), cbr(c4, c4), cbr(c4, c4))     # /16
        self.s32 = nn.Sequential(cbr(c4, c5, 2), cbr(c5, c5), cbr(c5, c5))     # /32
        self.lat32 = cbr(c5, neck, k=1)
        self.lat16 = cbr(c4, neck, k=1)
        self.lat8 = cbr(c3, neck, k=1)
        self.fuse16 = cbr(neck, neck)
        self.fuse8 = cbr(neck, neck)
        self.lat4 = cbr(c2, head, k=1)
        self.red8 = cbr(neck, head, k=1)
        self.fuse4 = cbr(head, head)
        self.shared = cbr(head, head)
        self.hm_out = nn.Conv2d(head, 1, 1)
        self.box_out = nn.Conv2d(head, 4, 1)
        nn.init.constant_(self.hm_out.bias, -2.19)  # prior p = 0.1 (CenterNet)
        nn.init.constant_(self.box_out.bias, 2.0)

    def features(self, x: torch.Tensor) -> torch.Tensor:
        f4 = self.s4(x)
        f8 = self.s8(f4)
        f16 = self.s16(f8)
        f32 = self.s32(f16)
        p = self.lat32(f32)
        p = self.fuse16(self.lat16(f16) + F.interpolate(p, size=f16.shape[-2:], mode="nearest"))
        p = self.fuse8(self.lat8(f8) + F.interpolate(p, size=f8.shape[-2:], mode="nearest"))
        p = self.fuse4(self.lat4(f4) + F.interpolate(self.red8(p), size=f4.shape[-2:], mode="nearest"))
        return self.shared(p)

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """x: (B, 3, H, W) RGB in [0, 1] -> (heatmap logits (B,1,H/4,W/4), ltrb px (B,4,H/4,W/4))."""
        p = self.features(x - 0.5)
        return self.hm_out(p), self.box_out(p) * float(self.stride)


class ExportWrapper(nn.Module):
    """Inference graph: sigmoid on the heatmap; outputs named ``heatmap`` and ``ltrb``."""

    def __init__(self, net: CenterNetVehicle) -> None:
        super().__init__()
        self.net = net

    def forward(self, image: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        hm, ltrb = self.net(image)
        return torch.sigmoid(hm), ltrb


#: named widths (``train --size``; the checkpoint records its size). small: 401k parameters (1.6 MB), the shipped
#: models; large: 2.42M (9.7 MB), about twice the compute (most of it at strides 8-32)
SIZES: dict[str, dict] = {
    "small": {},
    "large": {"width": (24, 48, 96, 160, 256), "neck": 64, "head": 32},
}


def of_size(size: str = "small") -> CenterNetVehicle:
    """A fresh net of a named size (:data:`SIZES`)."""
    if size not in SIZES:
        raise ValueError(f"unknown net size {size!r}; known: {', '.join(SIZES)}")
    return CenterNetVehicle(**SIZES[size])


def n_params(net: nn.Module) -> int:
    return sum(p.numel() for p in net.parameters())
