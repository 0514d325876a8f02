"""Training of the pairwise cost network :class:`~pasta.nn.cost.PairCost`.

Pairs of entities are drawn from the demonstration steps: a share from the same demonstration (close
shapes and positions, small distances) and the rest from anywhere (large distances). The label is the
Chamfer distance (:func:`pasta.core.metrics.chamfer`) of the two real entity clouds; the network
regresses ``log(chamfer + EPS)`` with a mean squared error. With ``flat=true`` (Flat 3D) the entities
are whole scenes.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, cast

import numpy as np
import torch
from torch import nn

from pasta.core.errors import InputError
from pasta.nn.cost import EPS, MODULE, PairCost
from pasta.train.latents import EncodedDemo


@dataclass
class CostTrainConfig:
    """Cost settings (``key=value`` on ``pasta train cost``).

    Attributes:
        hidden: network width.
        pairs_per_entity: pairs drawn per entity.
        same_demo_fraction: share of pairs taken inside one demonstration.
        label_points: points per entity used for the Chamfer label.
        num_points, stride, val_fraction: as for the VAE.
        vae: trained VAE directory (default ``OUT/vae``).
        flat: Flat 3D baseline: pairs of whole scenes (latents of the ``flat`` encoder, ``OUT/vae``
            must be a scene VAE): every ``stride``-th step of each demonstration and the dough after
            the skill, see :func:`pasta.train.latents.encode_scenes`.
        translated_fraction: share of the pairs (taken from both kinds above) whose second entity is
            replaced by the first one moved by a random offset: the same shape code ``z``, the centroid
            ``t`` plus the offset, and the exact Chamfer of the moved cloud as label. Demonstration pairs
            almost never differ in height (all dough rests on the floor), so a network trained on them
            alone rated a piece 3.5 cm too high 9x too close (7e-5 against a true 6.4e-4, while x and z
            came out right) and the planner left sub-goals at the wrong height (docs/learning.md).
        translate_max: the offsets' largest length (uniform in length, uniform direction in space).
    """

    hidden: int = 256
    pairs_per_entity: int = 8
    same_demo_fraction: float = 0.5
    label_points: int = 400
    num_points: int = 1000
    stride: int = 1
    val_fraction: float = 0.2
    vae: str = ""
    flat: bool = False
    translated_fraction: float = 0.0
    translate_max: float = 0.1

    def __post_init__(self) -> None:
        from pasta.config.validate import check_ranges
        from pasta.train.vae import MAX_POINTS

        check_ranges(self, {"hidden": (1, 1 << 16), "pairs_per_entity": (1, 10_000), "same_demo_fraction": (0.0, 1.0),
                            "label_points": (1, MAX_POINTS), "num_points": (1, MAX_POINTS), "stride": (1, None),
                            "val_fraction": (0.0, 1.0, "[)"), "translated_fraction": (0.0, 1.0),
                            "translate_max": (0.0, None)})


def entity_pairs(demos: list[EncodedDemo], cfg: CostTrainConfig, *, seed: int = 0) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """``(a (B, D), b (B, D), chamfer (B,))`` pairs of entities of ``demos`` with their true distance."""
    from pasta.core.metrics import chamfer

    latents = torch.cat([u for d in demos for u in d.latents])
    clouds = torch.cat([c[:, : cfg.label_points] for d in demos for c in d.clouds])
    owner = torch.cat([torch.full((len(u),), k) for k, d in enumerate(demos) for u in d.latents])
    if len(latents) < 2:
        raise InputError("need at least two entities to train the cost model")
    rng = np.random.default_rng(seed)
    first = np.repeat(np.arange(len(latents)), cfg.pairs_per_entity)
    second = rng.integers(0, len(latents), len(first))
    same = rng.random(len(first)) < cfg.same_demo_fraction
    members = [np.flatnonzero(owner.numpy() == k) for k in range(len(demos))]
    for row in np.flatnonzero(same):
        group = members[int(owner[first[row]])]
        second[row] = group[rng.integers(len(group))]
    first_t, second_t = torch.from_numpy(first), torch.from_numpy(second)
    a, b = latents[first_t], latents[second_t].clone()
    offsets = torch.zeros(len(first), 3)
    moved = torch.from_numpy(rng.random(len(first)) < cfg.translated_fraction)
    if moved.any():  # the first entity again, moved: same z, centroid t (the last 3 numbers) + offset
        n = int(moved.sum())
        direction = torch.from_numpy(rng.normal(size=(n, 3))).float()
        direction /= direction.norm(dim=1, keepdim=True).clamp(min=1e-12)
        offsets[moved] = direction * torch.from_numpy(rng.random((n, 1)) * cfg.translate_max).float()
        b[moved] = a[moved]
        b[moved, -3:] += offsets[moved]
    labels = []
    for i in range(0, len(first), 256):  # in chunks: all pairs' clouds at once would be ~0.25 GB per copy
        one, two = clouds[first_t[i : i + 256]], clouds[second_t[i : i + 256]]
        m = moved[i : i + 256]
        if m.any():
            two = torch.where(m[:, None, None], one + offsets[i : i + 256, None, :], two)
        labels.append(chamfer(one, two))
    return a, b, torch.cat(labels)


class CostTask:
    """:class:`pasta.train.loop.TrainTask` of the pairwise cost."""

    module = MODULE

    def __init__(self, train: tuple, val: tuple, latent_dim: int, cfg: CostTrainConfig, *, seed: int = 0) -> None:
        self.cfg = cfg
        torch.manual_seed(seed)
        self.model = PairCost(latent_dim, cfg.hidden)
        self.train_a, self.train_b, self.train_c = train
        self.val_a, self.val_b, self.val_c = val if len(val[0]) else train
        with torch.no_grad():  # start at the mean log-distance so early epochs are not spent on the offset
            cast(nn.Linear, self.model.net[-1]).bias.fill_(float(torch.log(self.train_c + EPS).mean()))

    def config(self) -> dict[str, Any]:
        from pasta.train.feasibility import scope_config, train_dict

        return {**self.model.config(), **scope_config(self.cfg), "train": train_dict(self.cfg)}

    def batches(self, batch_size: int, generator: torch.Generator):
        order = torch.randperm(len(self.train_a), generator=generator)
        for i in range(0, len(order), batch_size):
            yield order[i : i + batch_size]

    def loss(self, batch: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
        pred = self.model.log_cost(self.train_a[batch], self.train_b[batch])
        return (pred - torch.log(self.train_c[batch] + EPS)).pow(2).mean()

    @torch.no_grad()
    def validate(self) -> dict[str, float]:
        from scipy.stats import spearmanr

        log_pred = self.model.log_cost(self.val_a, self.val_b)
        pred = self.model.cost(self.val_a, self.val_b)
        rho = spearmanr(pred.numpy(), self.val_c.numpy()).statistic
        return {
            "val_loss": float((log_pred - torch.log(self.val_c + EPS)).pow(2).mean()),
            "val_spearman": float(rho),
            "val_mae": float((pred - self.val_c).abs().mean()),
        }
