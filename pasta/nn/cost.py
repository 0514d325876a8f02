"""Pairwise entity cost: a network predicting the Chamfer distance of two entities from their latents.

The network sees ``(z_a, z_b, t_a - t_b)``, i.e. only the relative translation, and is symmetrised
(``c(a, b) = c(b, a)``). It regresses ``log(chamfer + EPS)``; the cost is ``max(exp(s) - EPS, 0)`` so
two identical entities cost (nearly) 0. The set cost is the minimum over matchings, computed by
:class:`pasta.core.CostModel` (enumerated for <= 4 entities, Hungarian beyond).
"""

from __future__ import annotations

from typing import Any

import torch
from torch import nn

from pasta.core import CostModel, MissingComponentError
from pasta.core.errors import InputError
from pasta.nn.layers import mlp

#: offset of the log-space regression target, in Chamfer units (m^2)
EPS = 1e-5
MODULE = "set_cost"


class PairCost(nn.Module):
    """``a (..., D)``, ``b (..., D)`` -> log-cost ``(...)``; :meth:`cost` gives the Chamfer estimate."""

    def __init__(self, latent_dim: int, hidden: int = 256) -> None:
        super().__init__()
        self.latent_dim, self.hidden = latent_dim, hidden
        z = latent_dim - 3
        self.net = mlp([2 * z + 3, hidden, hidden, hidden, 1])

    def config(self) -> dict[str, int]:
        return {"latent_dim": self.latent_dim, "hidden": self.hidden}

    def log_cost(self, a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
        z = self.latent_dim - 3
        za, zb, dt = a[..., :z], b[..., :z], a[..., z:] - b[..., z:]
        forward = self.net(torch.cat([za, zb, dt], -1))
        backward = self.net(torch.cat([zb, za, -dt], -1))
        return (0.5 * (forward + backward)).squeeze(-1)

    def cost(self, a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
        """Predicted Chamfer distance (>= 0) of entity pairs ``a (..., D)``, ``b (..., D)`` -> ``(...)``."""
        return (self.log_cost(a, b).exp() - EPS).clamp(min=0.0)


class SetCostModel(CostModel):
    """The ``set_cost`` plugin: :class:`PairCost` loaded from ``config.weights``.

    Args:
        config: a :class:`pasta.nn.config.SetCostConfig`.
        model: an already built :class:`PairCost` (skips loading; for tests and training).
    """

    def __init__(self, config: Any = None, *, model: PairCost | None = None) -> None:
        from pasta.nn.config import SetCostConfig

        super().__init__(config or SetCostConfig())
        if model is None:
            from pasta.weights import ROOT

            model = load_pair_cost(self.config.weights or str(ROOT / "cost"), device=self.config.device)
        self.model = model.eval()

    @property
    def latent_dim(self) -> int:
        return self.model.latent_dim

    def pairwise(self, a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
        """Predicted Chamfer distance of every pair: ``a (B, K, D)``, ``b (B, G, D)`` -> ``(B, K, G)``."""
        if a.ndim != 3 or b.ndim != 3 or a.shape[0] != b.shape[0] or a.shape[-1] != b.shape[-1]:
            raise InputError(f"set_cost expects a (B, K, D) and b (B, G, D), got {tuple(a.shape)} and {tuple(b.shape)}")
        if a.shape[-1] != self.latent_dim:
            raise InputError(f"set_cost was trained on latents of size D = {self.latent_dim}, got {a.shape[-1]}")
        k, g = a.shape[1], b.shape[1]
        return self.model.cost(a[:, :, None, :].expand(-1, k, g, -1), b[:, None, :, :].expand(-1, k, g, -1))


def load_pair_cost(directory: str, *, device: str = "cpu", latent_dim: int | None = None,
                   scope: str = "entity") -> PairCost:
    """Load a trained :class:`PairCost` from ``directory`` (checks module, ``latent_dim`` if given, and
    ``scope``: ``"entity"``; ``"scene"`` accepts only Flat 3D networks, trained with ``flat=true``)."""
    from pasta.io.checkpoint import load_checkpoint

    if not directory:
        raise MissingComponentError("set_cost has no weights path: train one with `pasta train cost data=DIR out=models`")
    expect = {k: v for k, v in (("latent_dim", latent_dim), ("scope", scope)) if v is not None} or None
    ckpt = load_checkpoint(directory, module=MODULE, expect=expect,
                           hint="train one with `pasta train cost data=DIR out=models` (writes models/cost)")
    model = PairCost(ckpt.config["latent_dim"], ckpt.config["hidden"])
    model.load_state_dict(ckpt.tensors)
    return model.requires_grad_(False).to(device)
