"""Point-cloud VAE of one entity (or of a whole scene for the Flat 3D baseline).

- Encoder: PointNet over the centred cloud divided by a global scale -> Gaussian ``(mean, logvar)`` of
  ``z`` (``Z`` numbers).
- Decoder: a folding network: template points of the cube ``[-1, 1]^3`` are folded, conditioned on
  ``z``, into the centred shape (twice, the second fold a residual refinement). Any number of points
  can be decoded; decoding uses a fixed Sobol template, so it is deterministic.
- Buffers saved with the weights: ``scale`` (global std of centred training points) and the box of
  training centroids ``t_low`` / ``t_high`` (the prior of ``t`` and the planner's clamp).
"""

from __future__ import annotations

from typing import Any, cast

import torch
from torch import nn

from pasta.nn.layers import PointNet, mlp


def cube_template(n: int, *, generator: torch.Generator | None = None, device: Any = None) -> torch.Tensor:
    """``(n, 3)`` template points in ``[-1, 1]^3``: uniform random with ``generator``, else a fixed Sobol set."""
    if generator is not None:
        return torch.rand(n, 3, generator=generator).mul(2).sub(1).to(device)
    engine = torch.quasirandom.SobolEngine(3, scramble=False)
    engine.fast_forward(1)  # skip the corner (0, 0, 0)
    return engine.draw(n).mul(2).sub(1).to(device)


class PointVAE(nn.Module):
    """VAE over centred point clouds.

    Args:
        z_dim: ``Z``, size of the shape code.
        width: PointNet / MLP width.
        fold_hidden: hidden size of the folding decoder.
    """

    scale: torch.Tensor  # buffers (register_buffer)
    t_low: torch.Tensor
    t_high: torch.Tensor

    def __init__(self, z_dim: int = 2, width: int = 256, fold_hidden: int = 128) -> None:
        super().__init__()
        self.z_dim = z_dim
        self.pointnet = PointNet(3, (64, 128, width))
        self.head = mlp([width, width, 2 * z_dim])
        self.z_embed = mlp([z_dim, 64, 64], last_activation=True)
        self.fold1 = mlp([3 + 64, fold_hidden, fold_hidden, 3])
        self.fold2 = mlp([3 + 64, fold_hidden, fold_hidden, 3])
        self.register_buffer("scale", torch.ones(()))
        self.register_buffer("t_low", torch.zeros(3))
        self.register_buffer("t_high", torch.ones(3))

    def config(self) -> dict[str, int]:
        return {"z_dim": self.z_dim, "width": self.pointnet.out_dim, "fold_hidden": cast(nn.Linear, self.fold1[0]).out_features}

    def encode_stats(self, centred: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """``centred (B, P, 3)`` (world units, centroid removed) -> ``(mean (B, Z), logvar (B, Z))``."""
        mean, logvar = self.head(self.pointnet(centred / self.scale)).chunk(2, -1)
        return mean, logvar.clamp(-12.0, 6.0)

    def decode_normalised(self, z: torch.Tensor, template: torch.Tensor) -> torch.Tensor:
        """``z (B, Z)`` and ``template (Q, 3)`` -> ``(B, Q, 3)`` centred points in units of ``scale``."""
        b, q = z.shape[0], template.shape[0]
        e = self.z_embed(z)[:, None, :].expand(b, q, -1)
        grid = template[None].expand(b, q, 3)
        first = self.fold1(torch.cat([grid, e], -1))
        return first + self.fold2(torch.cat([first, e], -1))

    def decode_centred(self, z: torch.Tensor, num_points: int) -> torch.Tensor:
        """``z (B, Z)`` -> ``(B, num_points, 3)`` centred points in world units (deterministic)."""
        template = cube_template(num_points, device=z.device).to(z.dtype)
        return self.decode_normalised(z, template) * self.scale


MODULE = "vae"
TRAIN_HINT = {
    "entity": "train one with `pasta train vae data=DIR out=models` (writes models/vae)",
    "scene": "train one with `pasta train vae data=DIR out=models/flat flat=true` (writes models/flat/vae)",
}


def load_vae(directory: str, *, scope: str = "entity", device: str = "cpu") -> PointVAE:
    """Load a trained :class:`PointVAE` of ``scope`` ``"entity"`` or ``"scene"`` (flat) from ``directory``."""
    from pasta.core.errors import MissingComponentError
    from pasta.io.checkpoint import load_checkpoint

    if not directory:
        raise MissingComponentError(f"no VAE weights path given: {TRAIN_HINT[scope]}")
    ckpt = load_checkpoint(directory, module=MODULE, expect={"scope": scope}, hint=TRAIN_HINT[scope])
    cfg = ckpt.config
    model = PointVAE(cfg["z_dim"], cfg["width"], cfg["fold_hidden"])
    model.load_state_dict(ckpt.tensors)
    return model.requires_grad_(False).to(device).eval()
