"""The Encoder contract: entity point clouds <-> entity latents ``u = [z, t]``.

``z`` (``Z`` numbers) codes the shape of the centred entity and ``t`` (3 numbers) is its centroid, so
``D = Z + 3``. The planner samples new entities from :meth:`Encoder.sample_prior` and keeps ``t``
inside the box of training centroids with :meth:`Encoder.clamp`.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import numpy as np
    import torch


class Encoder(ABC):
    """Base class of encoder plugins.

    Subclasses set :attr:`z_dim` and the centroid box :attr:`t_low` / :attr:`t_high` (3 floats each).
    """

    z_dim: int
    t_low: tuple[float, float, float] = (0.0, 0.0, 0.0)
    t_high: tuple[float, float, float] = (1.0, 1.0, 1.0)

    def __init__(self, config: Any = None) -> None:
        self.config = config

    @property
    def latent_dim(self) -> int:
        """``D = Z + 3``."""
        return self.z_dim + 3

    @abstractmethod
    def encode(self, points: torch.Tensor) -> torch.Tensor:
        """Encode entities ``(K, P, 3)`` to latents ``(K, D)`` (posterior mean for a VAE)."""

    @abstractmethod
    def decode(self, latents: torch.Tensor, num_points: int) -> torch.Tensor:
        """Decode latents ``(K, D)`` to point clouds ``(K, P, 3)`` with ``P = num_points``."""

    def decode_clouds(self, latents: Any, num_points: int) -> list[np.ndarray]:
        """Decode ``(K, D)`` latents (a tensor, also one that tracks gradients, or any array-like) into ``K``
        float32 clouds ``(num_points, 3)``, without gradients: what the executor hands a controller as a
        sub-goal, what a summary draws, what the reset pose's decoded-goal augmentation trains on."""
        import numpy as np
        import torch

        if len(latents) == 0:
            return []
        if isinstance(latents, torch.Tensor):
            x = latents.detach().to("cpu", torch.float32)
        else:
            x = torch.as_tensor(np.asarray(latents, np.float32))
        with torch.no_grad():
            out = self.decode(x, num_points)
        clouds = out.detach().cpu().numpy() if hasattr(out, "detach") else np.asarray(out)
        return [np.asarray(c, np.float32) for c in clouds]

    @abstractmethod
    def sample_prior(self, n: int, generator: torch.Generator) -> torch.Tensor:
        """Draw ``(n, D)`` latents: ``z`` from the prior, ``t`` uniform in the centroid box."""

    def clamp(self, latents: torch.Tensor) -> torch.Tensor:
        """Return ``latents (..., D)`` with ``t`` clamped into ``[t_low, t_high]`` (differentiable copy)."""
        import torch

        low = torch.tensor(self.t_low, dtype=latents.dtype, device=latents.device)
        high = torch.tensor(self.t_high, dtype=latents.dtype, device=latents.device)
        return torch.cat([latents[..., : self.z_dim], torch.maximum(torch.minimum(latents[..., self.z_dim :], high), low)], -1)
