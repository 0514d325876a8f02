"""Settings of the 'exhaustive' planner."""

from __future__ import annotations

from dataclasses import dataclass

from pasta.planning import HalvingConfig


@dataclass
class ExhaustiveConfig(HalvingConfig):
    """every skill sequence with the right cardinality, random attention, Adam on sub-goal latents (PASTA)."""

    # 0: only sequences of the problem's horizon H; N > 0: every horizon 1..N, optimised in one batch
    # (ignored when the problem gives a skeleton).
    max_horizon: int = 0

    def __post_init__(self) -> None:
        from pasta.config import MAX_HORIZON
        from pasta.config.validate import check_int

        super().__post_init__()
        check_int(self.max_horizon, "planner.max_horizon", low=0, high=MAX_HORIZON)  # as horizon=: K**H sequences
