"""Settings of the 'receding_horizon' planner."""

from __future__ import annotations

from dataclasses import dataclass

from pasta.planning.config import LatentPlannerConfig


@dataclass
class RecedingHorizonConfig(LatentPlannerConfig):
    """optimise a window of steps, commit the first, slide (long tasks)."""

    window: int = 3  # steps optimised at once (paper: 3)
