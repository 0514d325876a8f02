"""PointNet++ in pure torch: farthest point sampling, ball query, set abstraction, global pooling.

Shapes: ``B`` batch, ``N`` input points, ``M`` sampled centres, ``K`` neighbours per centre, ``C``
feature channels. Everything is batched and runs on any torch device; no compiled extension.

Order invariance: farthest point sampling starts from the point farthest from the cloud's centroid
(not from index 0) and the ball query keeps the ``K`` *nearest* points inside the radius (not the
first ``K`` by index), so permuting the input points leaves the output unchanged (up to exact
distance ties, which have probability zero for real-valued clouds).
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass, field

import torch
from torch import nn

__all__ = [
    "PointNet2",
    "PointNet2Config",
    "SAConfig",
    "SetAbstraction",
    "ball_query",
    "farthest_point_sample",
    "gather_points",
]


def gather_points(values: torch.Tensor, idx: torch.Tensor) -> torch.Tensor:
    """Pick rows of ``values (B, N, C)`` at ``idx (B, ...)`` -> ``(B, ..., C)``."""
    b = values.shape[0]
    flat = idx.reshape(b, -1)
    out = torch.gather(values, 1, flat.unsqueeze(-1).expand(-1, -1, values.shape[-1]))
    return out.reshape(*idx.shape, values.shape[-1])


@torch.no_grad()
def farthest_point_sample(xyz: torch.Tensor, m: int, start: torch.Tensor | None = None) -> torch.Tensor:
    """Indices of ``m`` points of ``xyz (B, N, 3)`` chosen by farthest point sampling -> ``(B, m)`` int64.

    The first index is ``start (B,)`` if given, else the point farthest from the centroid; each next
    one maximises the distance to the already chosen set (first maximum on ties). ``m`` may exceed
    ``N``: once every point is chosen, the sampler repeats points (distances are all 0).
    """
    b, n, _ = xyz.shape
    if m < 1:
        raise ValueError(f"farthest_point_sample: m must be >= 1, got {m}")
    if start is None:
        start = (xyz - xyz.mean(1, keepdim=True)).pow(2).sum(-1).argmax(-1)
    idx = torch.empty(b, m, dtype=torch.long, device=xyz.device)
    dist = torch.full((b, n), float("inf"), dtype=xyz.dtype, device=xyz.device)
    cur = start.to(torch.long)
    rows = torch.arange(b, device=xyz.device)
    for i in range(m):
        idx[:, i] = cur
        d = (xyz - xyz[rows, cur].unsqueeze(1)).pow(2).sum(-1)
        dist = torch.minimum(dist, d)
        cur = dist.argmax(-1)
    return idx


@torch.no_grad()
def ball_query(xyz: torch.Tensor, centers: torch.Tensor, radius: float, k: int) -> torch.Tensor:
    """Neighbours of each centre: the ``k`` nearest points of ``xyz (B, N, 3)`` within ``radius`` of
    ``centers (B, M, 3)`` -> ``(B, M, k)`` int64 indices into ``N``.

    Slots beyond the points found inside the ball repeat the nearest point (a centre taken from
    ``xyz`` is its own nearest point), which leaves a max pooling unchanged.
    """
    k = min(k, xyz.shape[1])
    d = torch.cdist(centers, xyz)  # (B, M, N)
    dk, ik = d.topk(k, dim=-1, largest=False)  # sorted ascending
    outside = dk > radius
    return torch.where(outside, ik[..., :1].expand_as(ik), ik)


def _mlp(sizes: Sequence[int]) -> nn.Sequential:
    layers: list[nn.Module] = []
    for a, b in itertools.pairwise(sizes):
        layers += [nn.Linear(a, b), nn.ReLU()]
    return nn.Sequential(*layers)


@dataclass
class SAConfig:
    """One set-abstraction level: ``centers`` sampled by FPS, ``k`` neighbours within ``radius``,
    shared MLP ``widths`` applied to ``[features, xyz - centre]``."""

    centers: int
    radius: float
    k: int
    widths: tuple[int, ...]


def _default_levels() -> list[SAConfig]:
    return [SAConfig(128, 0.05, 16, (32, 32, 64)), SAConfig(32, 0.12, 16, (64, 64, 128))]


@dataclass
class PointNet2Config:
    """PointNet++ encoder sizes (defaults sized for CPU training on ~1,100 input points).

    Attributes:
        in_features: per-point feature channels besides xyz (3 for the one-hot source).
        levels: the set-abstraction levels.
        global_widths: MLP of the global level over ``[features, xyz]``, max-pooled to the output.
        pos_scale: positions are multiplied by this before entering an MLP (radii stay in world
            units); dough clouds span ~0.1, so a scale of 10 gives the MLPs inputs of order 1.
    """

    in_features: int = 3
    pos_scale: float = 10.0
    levels: list[SAConfig] = field(default_factory=_default_levels)
    global_widths: tuple[int, ...] = (128, 256, 512)

    @property
    def out_dim(self) -> int:
        return self.global_widths[-1]


class SetAbstraction(nn.Module):
    """``(xyz (B, N, 3), feats (B, N, C))`` -> ``(xyz (B, M, 3), feats (B, M, C'))``: FPS centres, ball
    query, shared MLP on ``[feats_j, xyz_j - centre]`` (PointConv message), max over neighbours."""

    def __init__(self, cfg: SAConfig, in_features: int, pos_scale: float = 1.0) -> None:
        super().__init__()
        self.cfg = cfg
        self.pos_scale = pos_scale
        self.mlp = _mlp([in_features + 3, *cfg.widths])

    def forward(self, xyz: torch.Tensor, feats: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        cidx = farthest_point_sample(xyz, min(self.cfg.centers, xyz.shape[1]))
        centers = gather_points(xyz, cidx)  # (B, M, 3)
        nidx = ball_query(xyz, centers, self.cfg.radius, self.cfg.k)  # (B, M, K)
        rel = (gather_points(xyz, nidx) - centers.unsqueeze(2)) * self.pos_scale
        grouped = torch.cat([gather_points(feats, nidx), rel], -1)  # (B, M, K, C + 3)
        return centers, self.mlp(grouped).amax(2)


class PointNet2(nn.Module):
    """PointNet++ encoder: ``(xyz (B, N, 3), feats (B, N, F))`` -> ``(B, cfg.out_dim)``.

    Every linear layer is followed by ReLU; no normalisation layers (so the output does not depend
    on the other clouds of the batch). Invariant to the order of the ``N`` points.
    """

    def __init__(self, cfg: PointNet2Config | None = None) -> None:
        super().__init__()
        self.cfg = cfg = cfg or PointNet2Config()
        levels, c = [], cfg.in_features
        for lv in cfg.levels:
            levels.append(SetAbstraction(lv, c, cfg.pos_scale))
            c = lv.widths[-1]
        self.levels = nn.ModuleList(levels)
        self.global_mlp = _mlp([c + 3, *cfg.global_widths])

    def forward(self, xyz: torch.Tensor, feats: torch.Tensor) -> torch.Tensor:
        for level in self.levels:
            xyz, feats = level(xyz, feats)
        return self.global_mlp(torch.cat([feats, xyz * self.cfg.pos_scale], -1)).amax(1)
