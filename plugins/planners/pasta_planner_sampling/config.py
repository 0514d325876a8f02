"""Settings of the 'sampling' planner."""

from __future__ import annotations

from dataclasses import dataclass

from pasta.planning import LatentPlannerConfig


@dataclass
class SamplingConfig(LatentPlannerConfig):
    """the same search without gradients: cross-entropy method over sub-goal latents."""

    num_samples: int = 1024  # CEM needs about 4x the samples of the gradient planner (docs/planning.md)
    elite_fraction: float = 0.1  # fraction of each (sequence, attention) population refitting its Gaussian
    min_std: float = 0.001  # floor of the refitted standard deviation

    def __post_init__(self) -> None:
        from pasta.config.validate import check_number

        super().__post_init__()
        check_number(self.elite_fraction, "planner.elite_fraction", low=0.0, high=1.0, low_open=True)
        check_number(self.min_std, "planner.min_std", low=0.0)
