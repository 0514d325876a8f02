"""Encoder plugins backed by a trained :class:`~pasta.nn.vae.PointVAE`.

- ``pc_vae`` (:class:`PointVAEEncoder`): one latent ``u = [z, t]`` per entity; ``t`` the centroid,
  ``z`` the posterior mean of the centred cloud.
- ``flat`` (:class:`FlatEncoder`): the same code trained on whole scenes; callers pass the whole dough
  cloud as one entity (``K = 1``), see :meth:`FlatEncoder.encode_scene`.
"""

from __future__ import annotations

from typing import Any, cast

import numpy as np
import torch

from pasta.core import Encoder
from pasta.core.errors import InputError
from pasta.nn.vae import PointVAE, load_vae


class PointVAEEncoder(Encoder):
    """Entity encoder over a trained point-cloud VAE.

    Args:
        config: a :class:`pasta.nn.config.PointVAEEncoderConfig` (``weights`` = trained VAE directory).
        model: an already built :class:`PointVAE` (skips loading; for tests and training).

    Raises:
        MissingComponentError: no trained weights at ``config.weights`` (the message gives the command).
    """

    scope = "entity"
    shipped_dir = "vae"  # under the shipped weights (pasta.weights) when config.weights is empty

    def __init__(self, config: Any = None, *, model: PointVAE | None = None) -> None:
        super().__init__(config or self._default_config())
        if model is None:
            from pasta.weights import ROOT

            weights = self.config.weights or str(ROOT / self.shipped_dir)
            model = load_vae(weights, scope=self.scope, device=self.config.device)
        self.model = model.eval()
        self.z_dim = model.z_dim
        # the (3,) buffers of every PointVAE
        self.t_low = cast(tuple[float, float, float], tuple(float(v) for v in model.t_low))
        self.t_high = cast(tuple[float, float, float], tuple(float(v) for v in model.t_high))

    @classmethod
    def _default_config(cls) -> Any:
        from pasta.nn.config import PointVAEEncoderConfig

        return PointVAEEncoderConfig()

    @property
    def _device(self) -> torch.device:
        return self.model.scale.device

    def encode(self, points: torch.Tensor) -> torch.Tensor:
        """Entities ``(K, P, 3)`` (torch or numpy) -> latents ``(K, D)``: posterior mean and centroid."""
        pts = torch.as_tensor(np.asarray(points) if not isinstance(points, torch.Tensor) else points)
        if pts.ndim != 3 or pts.shape[-1] != 3 or pts.shape[1] == 0:
            raise InputError(f"encode expects entity clouds (K, P, 3) with P >= 1, got {tuple(pts.shape)}")
        if not bool(pts.isfinite().all()):
            raise InputError("encode: point clouds contain NaN or infinite values")
        pts = pts.to(self._device, torch.float32)
        t = pts.mean(1)
        n = self.config.encode_points
        if pts.shape[1] > n:  # a fixed spread of indices keeps encoding deterministic
            pts = pts[:, torch.linspace(0, pts.shape[1] - 1, n, device=pts.device).round().long()]
        with torch.no_grad():
            mean, _ = self.model.encode_stats(pts - t[:, None, :])
        return torch.cat([mean, t], -1)

    def decode(self, latents: torch.Tensor, num_points: int) -> torch.Tensor:
        """Latents ``(K, D)`` -> clouds ``(K, num_points, 3)`` (deterministic)."""
        u = torch.as_tensor(latents, dtype=torch.float32, device=self._device)
        if u.ndim != 2 or u.shape[-1] != self.latent_dim:
            raise InputError(f"decode expects latents (K, {self.latent_dim}), got {tuple(u.shape)}")
        with torch.no_grad():
            centred = self.model.decode_centred(u[:, : self.z_dim], num_points)
        return centred + u[:, None, self.z_dim :]

    def sample_prior(self, n: int, generator: torch.Generator) -> torch.Tensor:
        """``(n, D)``: ``z ~ N(0, I)``, ``t`` uniform in the box of training centroids."""
        z = torch.randn(n, self.z_dim, generator=generator)
        low, high = torch.tensor(self.t_low), torch.tensor(self.t_high)
        t = low + torch.rand(n, 3, generator=generator) * (high - low)
        return torch.cat([z, t], -1)


class FlatEncoder(PointVAEEncoder):
    """The whole dough cloud as ONE latent (Flat 3D baseline); same network, trained on whole scenes."""

    scope = "scene"
    shipped_dir = "flat/vae"

    @classmethod
    def _default_config(cls) -> Any:
        from pasta.nn.config import FlatEncoderConfig

        return FlatEncoderConfig()

    def encode_scene(self, points: np.ndarray | torch.Tensor) -> torch.Tensor:
        """The whole cloud ``(P, 3)`` -> ``(1, D)``."""
        return self.encode(torch.as_tensor(np.asarray(points, dtype=np.float32))[None])
