"""The 'sampling' planner: PASTA's search without gradients (the paper's "no gradient" ablation)."""

from __future__ import annotations

from typing import Any

from pasta.planning import LatentPlanner
from pasta_planner_sampling.config import SamplingConfig


class SamplingPlanner(LatentPlanner):
    """Same candidates and batched evaluation as 'exhaustive'; the cross-entropy method moves the latents.

    One Gaussian per (sequence, attention structure); each iteration its elites (ranked by the log of
    the unfloored score) stay and the other samples are redrawn from the refitted Gaussian.
    """

    name = "sampling"
    method = "cem"
    config_class = SamplingConfig

    def search_options(self) -> dict[str, Any]:
        return {"elite_fraction": float(self.cfg.elite_fraction), "min_std": float(self.cfg.min_std)}
