"""Settings of the 'receding_horizon' planner."""

from __future__ import annotations

from dataclasses import dataclass

from pasta.planning import HalvingConfig


@dataclass
class RecedingHorizonConfig(HalvingConfig):
    """optimise a window of steps, commit the first, slide (long tasks)."""

    window: int = 3  # steps optimised at once (paper: 3)
