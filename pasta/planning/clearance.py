"""Clearance: a plan step should not move a piece through another piece.

PASTA's feasibility predictors see only the entities a step consumes and produces, so a latent plan
may push one piece straight through another that the step leaves alone: on cut_rearrange the planner
pushed the right half onto the left half, where the two merge into one piece (docs/planning.md,
"Clearance"). This module scores that in latent space, from the centroids ``t = u[Z:Z+3]``:

- every step moves its produced entities from the mean centroid of its consumed ones along a straight
  line on the floor plane (``x``, ``z``; ``y`` is up);
- every entity the step leaves alone is an obstacle: a box of its half extents, grown by the moving
  entity's (their Minkowski sum), measured in units of that sum, so ``d < 1`` is inside an ellipse
  inscribed in the overlap box (touching corners are tolerated);
- the penalty of a (moving, obstacle) pair is ``relu(min(d_start, 1) - d_min)``: positive only when
  the path comes closer to the obstacle than where it started, so separating neighbours (a cut's two
  halves, a piece pushed away from the rest of the dough) costs nothing.

Half extents come from the encoder's decoder: the start entities' own (decoded once per search) and,
for produced entities, the largest over the goal entities (their shapes change while the planner
optimises; decoded shapes are smaller than the dough, so the larger is the safer guess). A 1 -> 1 step
keeps its input's extents for the moved entity. A tool wider than the piece sweeps a wider band (the
pusher's paddle is 0.2 m long): on the way, a moved piece counts at least the step skill's
:attr:`~pasta.core.Skill.sweep_half_width` wide. The planner adds ``clearance_weight * penalty`` to the
plan cost (``planner.clearance_weight``, 0 disables).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import torch

__all__ = ["Clearance", "half_extents", "path_penalty"]

#: world axes of the floor plane (``y`` is up in the simulator and in every latent centroid)
FLOOR_AXES = (0, 2)


def half_extents(points: torch.Tensor) -> torch.Tensor:
    """Half extents on the floor plane of clouds ``(..., P, 3)`` -> ``(..., 2)``."""
    xz = points[..., list(FLOOR_AXES)]
    return 0.5 * (xz.amax(-2) - xz.amin(-2))


def path_penalty(start: torch.Tensor, end: torch.Tensor, move_extent: torch.Tensor, obstacles: torch.Tensor,
                 obstacle_extent: torch.Tensor, margin: float = 0.0) -> torch.Tensor:
    """Penalty of moving entities along straight paths past obstacles, summed per sample.

    Args:
        start: ``(B, 2)`` floor-plane point every moved entity starts from.
        end: ``(B, M, 2)`` where each of the ``M`` moved entities ends.
        move_extent: ``(B, M, 2)`` their half extents.
        obstacles: ``(B, K, 2)`` centroids of the entities left alone.
        obstacle_extent: ``(B, K, 2)`` their half extents.
        margin: added to every summed half extent (metres).

    Returns:
        ``(B,)`` sum over (moved, obstacle) pairs of ``relu(min(d_start, 1) - d_min)``.
    """
    if obstacles.shape[1] == 0 or end.shape[1] == 0:
        return start.new_zeros(start.shape[0])
    scale = (move_extent[:, :, None, :] + obstacle_extent[:, None, :, :] + margin).clamp(min=1e-4)  # (B, M, K, 2)
    a = (start[:, None, None, :] - obstacles[:, None, :, :]) / scale
    b = (end[:, :, None, :] - obstacles[:, None, :, :]) / scale
    ab = b - a
    t = (-(a * ab).sum(-1) / (ab * ab).sum(-1).clamp(min=1e-12)).clamp(0.0, 1.0)
    d_min = (a + t[..., None] * ab).norm(dim=-1)
    d_start = a.norm(dim=-1)
    return torch.relu(d_start.clamp(max=1.0) - d_min).sum((1, 2))


@dataclass
class Clearance:
    """What :func:`pasta.planning.batch.evaluate` needs to score clearance.

    Attributes:
        z_dim: shape-code size ``Z`` (the centroid is ``u[Z:Z+3]``).
        start_extent: ``(K_0, 2)`` half extents of the start entities.
        new_extent: ``(2,)`` half extents assumed for produced entities (the goal entities' largest).
        margin: metres added to every pair's summed half extents. Decoded shapes are thinner than the
            dough (our VAE's by about 0.01-0.03 m across the push direction) and pushed dough spreads.
        sweep: skill name -> its tool's :attr:`~pasta.core.Skill.sweep_half_width`.
    """

    z_dim: int
    start_extent: torch.Tensor
    new_extent: torch.Tensor
    margin: float = 0.04
    sweep: dict[str, float] = field(default_factory=dict)

    def sweep_widths(self, sequences: Sequence[Sequence[str]]) -> torch.Tensor:
        """``(S, H_max)`` each sequence step's :attr:`~pasta.core.Skill.sweep_half_width` (0-padded)."""
        longest = max((len(s) for s in sequences), default=0)
        return torch.tensor([[self.sweep.get(n, 0.0) for n in s] + [0.0] * (longest - len(s)) for s in sequences],
                            dtype=self.start_extent.dtype)

    @classmethod
    def from_problem(cls, encoder, start: torch.Tensor, goal: torch.Tensor, num_points: int = 256,
                     margin: float = 0.04, skills: Sequence[Any] = ()) -> Clearance:
        """Decode ``start (K_0, D)`` and ``goal (G, D)`` once and measure their extents; ``skills`` give
        their tools' sweep half widths."""
        with torch.no_grad():
            clouds = encoder.decode(torch.cat([start, goal]).detach(), num_points)
            ext = half_extents(torch.as_tensor(clouds, dtype=start.dtype))
        k = start.shape[0]
        sweep = {s.name: float(getattr(s, "sweep_half_width", 0.0)) for s in skills}
        return cls(int(encoder.z_dim), ext[:k], ext[k:].amax(0), float(margin), sweep)

    def floor(self, latents: torch.Tensor) -> torch.Tensor:
        """``(..., D)`` latents -> ``(..., 2)`` floor-plane centroids."""
        return latents[..., [self.z_dim + a for a in FLOOR_AXES]]

    def step_penalty(self, u_in: torch.Tensor, e_in: torch.Tensor, u_out: torch.Tensor, u_kept: torch.Tensor,
                     e_kept: torch.Tensor, sweep: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        """Penalty of one step and the extents of the set after it (produced entities first, as the state).

        Args:
            u_in: ``(B, N, D)`` consumed latents, ``e_in (B, N, 2)`` their extents.
            u_out: ``(B, M, D)`` produced latents.
            u_kept: ``(B, K - N, D)`` untouched latents, ``e_kept`` their extents.
            sweep: ``(B,)`` the step's tool sweep half width per sample (moved pieces count at least
                this wide on the way; the extents passed on are the pieces' own).

        Returns:
            ``(penalty (B,), extents of [produced, untouched] (B, M + K - N, 2))``.
        """
        b, m = u_out.shape[0], u_out.shape[1]
        if u_in.shape[1] == 1 and m == 1:
            e_out = e_in
        else:
            e_out = self.new_extent.to(u_out.dtype).expand(b, m, 2)
        start = self.floor(u_in).mean(1)
        e_move = e_out if sweep is None else torch.maximum(e_out, sweep.to(e_out.dtype)[:, None, None])
        penalty = path_penalty(start, self.floor(u_out), e_move, self.floor(u_kept), e_kept, self.margin)
        return penalty, torch.cat([e_out, e_kept], 1)
