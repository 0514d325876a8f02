"""Set feasibility network ``f_k(U_in (B, N, D), U_out (B, M, D)) -> (B,)`` in ``[0, 1]``.

Each side goes through its own per-entity MLP and is max-pooled over entities, so the score is
invariant to the order of the inputs and, separately, of the outputs. Translations are centred over
the tuple first (the mean centroid of all ``N + M`` entities is subtracted), so only relative
positions matter. The last ``3`` numbers of a latent are the centroid ``t``.
"""

from __future__ import annotations

from typing import Any

import torch
import torch.nn.functional as F
from torch import nn

from pasta.core.errors import InputError
from pasta.nn.layers import mlp


class SetFeasibility(nn.Module):
    """Feasibility of one skill.

    Args:
        n_in: ``N_k``, entities consumed (recorded for checks; any count works).
        n_out: ``M_k``, entities produced.
        latent_dim: ``D = Z + 3``.
        hidden: width of the per-entity and head MLPs.
    """

    #: how it was trained (set when loaded from a checkpoint)
    train_settings: dict[str, Any]

    def __init__(self, n_in: int, n_out: int, latent_dim: int, hidden: int = 256) -> None:
        super().__init__()
        self.n_in, self.n_out, self.latent_dim, self.hidden = n_in, n_out, latent_dim, hidden
        self.phi_in = mlp([latent_dim, hidden, hidden], last_activation=True)
        self.phi_out = mlp([latent_dim, hidden, hidden], last_activation=True)
        self.head = mlp([2 * hidden, hidden, hidden, 1])
        #: ``(low, high)`` centroids of the produced entities it was trained on (set when loaded; see
        #: :attr:`pasta.core.Skill.output_box`), ``None`` when not recorded
        self.output_box: tuple[tuple[float, ...], tuple[float, ...]] | None = None

    def config(self) -> dict[str, int]:
        return {"n_in": self.n_in, "n_out": self.n_out, "latent_dim": self.latent_dim, "hidden": self.hidden}

    def logits(self, u_in: torch.Tensor, u_out: torch.Tensor) -> torch.Tensor:
        """Pre-sigmoid scores ``(B,)`` (used by the training loss)."""
        if u_in.ndim != 3 or u_out.ndim != 3 or u_in.shape[-1] != self.latent_dim or u_out.shape[-1] != self.latent_dim:
            raise InputError(
                f"feasibility expects U_in (B, N, {self.latent_dim}) and U_out (B, M, {self.latent_dim}), "
                f"got {tuple(u_in.shape)} and {tuple(u_out.shape)}"
            )
        centre = torch.cat([u_in[..., -3:], u_out[..., -3:]], 1).mean(1, keepdim=True)
        shift = F.pad(centre, (self.latent_dim - 3, 0))  # zeros over z, the mean centroid over t
        pooled_in = self.phi_in(u_in - shift).amax(1)
        pooled_out = self.phi_out(u_out - shift).amax(1)
        return self.head(torch.cat([pooled_in, pooled_out], -1)).squeeze(-1)

    def forward(self, u_in: torch.Tensor, u_out: torch.Tensor) -> torch.Tensor:
        """Feasibility ``(B,)`` in ``[0, 1]`` of ``u_in (B, N, D)`` -> ``u_out (B, M, D)``."""
        return torch.sigmoid(self.logits(u_in, u_out))
