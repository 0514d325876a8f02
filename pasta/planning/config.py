"""Settings shared by the latent-optimising planners (paper defaults in comments)."""

from __future__ import annotations

from dataclasses import dataclass

from pasta.core import PluginConfig


@dataclass
class LatentPlannerConfig(PluginConfig):
    """Objective ``prod_h max(f_h, floor) * exp(-cost_weight * C) + aux_weight * sum_h f_h``."""

    num_samples: int = 5000  # attention + sub-goal samples per skill sequence (paper 5000)
    iterations: int = 100  # optimiser iterations (paper 100-300)
    lr: float = 0.01  # Adam learning rate on the sub-goal latents (paper 0.01)
    cost_weight: float = 100.0  # lambda (paper: 100 for CRS-type tasks, 10 otherwise)
    feasibility_floor: float = 0.01
    aux_weight: float = 0.01
