"""Pressure and Peak CNNs (thesis section 7), sized for CPU training and fast inference.

Both models take the input grids [N, 6, 61, 61] and return impulse grids [N, 2, 61, 61].
Per-channel input and output scales are buffers inside the model, so the exported ONNX works on
raw grids and returns raw impulses. Only ops that tract 0.23 and ONNX Runtime both run are used:
Conv (BatchNorm folds into it at export), Relu, AveragePool (ceil_mode), Resize (bilinear,
align_corners), Add, Mul, Min, Gemm, Reshape/Flatten.
"""

from __future__ import annotations

import torch
from torch import nn
import torch.nn.functional as F

GRID = 61


def up(x: torch.Tensor, size: int = GRID) -> torch.Tensor:
    """Bilinear resize to size x size; align_corners makes the mapping unambiguous across runtimes."""
    if x.shape[-1] == size and x.shape[-2] == size:
        return x
    return F.interpolate(x, size=(size, size), mode="bilinear", align_corners=True)


def conv_bn(cin: int, cout: int, k: int = 3, relu: bool = True) -> nn.Sequential:
    layers = [nn.Conv2d(cin, cout, k, padding=k // 2, bias=False), nn.BatchNorm2d(cout)]
    if relu:
        layers.append(nn.ReLU())
    return nn.Sequential(*layers)


class Scaled(nn.Module):
    """Holds the fixed input caps and scales and the output scales (set from the training data).

    The input is `min(x, in_cap) * in_scale`: the cap keeps the wall mass (100, some 500 times
    a body node's mass) from swamping the normalisation; only the mass channel is capped.
    """

    def __init__(self, cin: int = 6, cout: int = 2, mass_cap: float = 2.0):
        super().__init__()
        cap = torch.full((1, cin, 1, 1), 1e30)
        cap[0, 0] = mass_cap
        self.register_buffer("in_cap", cap)
        self.register_buffer("in_scale", torch.ones(1, cin, 1, 1))
        self.register_buffer("out_scale", torch.ones(1, cout, 1, 1))

    def prepare(self, x: torch.Tensor) -> torch.Tensor:
        return torch.minimum(x, self.in_cap) * self.in_scale


class Pressure(Scaled):
    """Pressure (after Tompson et al. 2016, as modified in the thesis).

    conv 3x3 x c + BN + ReLU; average pools (2x2, stride 2, ceil) give three scales 61, 31, 16;
    at each scale two conv 3x3 x c + BN (+ReLU); bilinear resize to 61 and sum; then 1x1 convs
    to 8 and 4 (+BN, ReLU) and a linear 1x1 conv to the 2 output channels.
    Deviation from the thesis: 3x3 kernels instead of 4x4 (symmetric 'same' padding, ~half the
    cost) and c = 8 filters instead of 16 (4x cheaper inference: ~2 ms instead of ~8 ms per step on one core with tract).
    """

    def __init__(self, c: int = 8, cin: int = 6):
        super().__init__(cin=cin)
        self.stem = conv_bn(cin, c)
        self.scales = nn.ModuleList([nn.Sequential(conv_bn(c, c), conv_bn(c, c)) for _ in range(3)])
        self.head = nn.Sequential(
            conv_bn(c, 8, k=1), conv_bn(8, 4, k=1), nn.Conv2d(4, 2, 1)
        )

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        x = self.stem(self.prepare(x))
        s1 = F.avg_pool2d(x, 2, 2, ceil_mode=True)  # 31
        s2 = F.avg_pool2d(s1, 2, 2, ceil_mode=True)  # 16
        y = self.scales[0](x) + up(self.scales[1](s1)) + up(self.scales[2](s2))
        return self.head(y) * self.out_scale


class Peak(Scaled):
    """Peak (the thesis's own model), with far smaller dense layers.

    Four blocks conv 3x3 (8, 16, 32, 64) + ReLU + BN + average pool (61 -> 31 -> 16 -> 8 -> 4);
    each block's output goes through a 1x1 conv to 6 channels, is resized bilinearly to 61 and
    summed with the (scaled) input. The thesis then flattened the 6x61x61 sum into dense layers of
    ~0.9 billion weights. Here the dense part works on a 4x4-average-pooled summary instead:
    1x1 conv 6 -> 2, pool to 2x16x16 (512), Gemm 512 -> 256 + ReLU, Gemm 256 -> 512, reshape
    to 2x16x16 and resize to 61 (global context, ~0.26 M weights), added to a per-node 1x1 conv
    head (6 -> 16 -> 2) on the multi-scale sum (local detail).
    """

    def __init__(self, hidden: int = 256):
        super().__init__()
        widths = [8, 16, 32, 64]
        self.blocks = nn.ModuleList()
        self.side = nn.ModuleList()
        cin = 6
        for w in widths:
            self.blocks.append(conv_bn(cin, w))
            self.side.append(nn.Conv2d(w, 6, 1))
            cin = w
        self.local = nn.Sequential(nn.Conv2d(6, 16, 1), nn.ReLU(), nn.Conv2d(16, 2, 1))
        self.squeeze = nn.Conv2d(6, 2, 1)
        self.dense = nn.Sequential(nn.Linear(2 * 16 * 16, hidden), nn.ReLU(), nn.Linear(hidden, 2 * 16 * 16))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        x = self.prepare(x)
        total = x
        h = x
        for block, side in zip(self.blocks, self.side):
            h = F.avg_pool2d(block(h), 2, 2, ceil_mode=True)
            total = total + up(side(h))
        g = F.avg_pool2d(self.squeeze(total), 4, 4, ceil_mode=True)  # [N, 2, 16, 16]
        g = self.dense(torch.flatten(g, 1)).reshape(-1, 2, 16, 16)
        return (self.local(total) + up(g)) * self.out_scale


MODELS = {"pressure": Pressure, "peak": Peak}


def parameter_count(model: nn.Module) -> int:
    return sum(p.numel() for p in model.parameters() if p.requires_grad)
