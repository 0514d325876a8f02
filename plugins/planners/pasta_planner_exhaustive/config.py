"""Settings of the 'exhaustive' planner."""

from __future__ import annotations

from dataclasses import dataclass

from pasta.planning.config import LatentPlannerConfig


@dataclass
class ExhaustiveConfig(LatentPlannerConfig):
    """every skill sequence with the right cardinality, random attention, Adam on sub-goal latents (PASTA)."""
    successive_halving: bool = False  # drop the worse half of the samples at fixed fractions of the iterations
