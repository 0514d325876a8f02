"""Small building blocks: MLPs and a PointNet (shared per-point MLP + max pooling)."""

from __future__ import annotations

import itertools
from collections.abc import Sequence

import torch
from torch import nn


def mlp(sizes: Sequence[int], *, last_activation: bool = False) -> nn.Sequential:
    """Linear layers ``sizes[0] -> ... -> sizes[-1]`` with ReLU between them (and after the last if asked)."""
    layers: list[nn.Module] = []
    for i, (a, b) in enumerate(itertools.pairwise(sizes)):
        layers.append(nn.Linear(a, b))
        if i < len(sizes) - 2 or last_activation:
            layers.append(nn.ReLU())
    return nn.Sequential(*layers)


class PointNet(nn.Module):
    """Per-point MLP then max pooling: ``(B, P, C)`` -> ``(B, widths[-1])``, invariant to point order."""

    def __init__(self, in_dim: int = 3, widths: Sequence[int] = (64, 128, 256)) -> None:
        super().__init__()
        self.point_mlp = mlp([in_dim, *widths])
        self.out_dim = widths[-1]

    def forward(self, points: torch.Tensor) -> torch.Tensor:
        return self.point_mlp(points).amax(-2)
