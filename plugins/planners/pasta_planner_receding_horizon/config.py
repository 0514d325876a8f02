"""Settings of the 'receding_horizon' planner."""

from __future__ import annotations

from dataclasses import dataclass

from pasta.planning import HalvingConfig


@dataclass
class RecedingHorizonConfig(HalvingConfig):
    """optimise a window of steps, commit the first, slide (long tasks)."""

    window: int = 3  # steps optimised at once (paper: 3)

    def __post_init__(self) -> None:
        from pasta.config import MAX_HORIZON
        from pasta.config.validate import check_int

        super().__post_init__()
        check_int(self.window, "planner.window", low=1, high=MAX_HORIZON)  # as horizon=: K**window sequences
