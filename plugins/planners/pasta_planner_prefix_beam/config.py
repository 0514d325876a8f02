"""Settings of the 'prefix_beam' planner."""

from __future__ import annotations

from dataclasses import dataclass

from pasta.planning import HalvingConfig


@dataclass
class PrefixBeamConfig(HalvingConfig):
    """beam search over skill prefixes (warm-started window searches), then the shared optimiser on the best full sequences."""

    width: int = 3  # prefixes kept per depth and entity count
    # steps re-optimised when a prefix is extended: the last `window` steps, from the set the parent reached
    # before them (1: only the new step, from the parent's end set)
    window: int = 2
    # complete sequences optimised at the end (num_samples / iterations as above). The defaults (final 24, polish
    # 3, sequence draws) planned crs at H=6 with exhaustive's plan and score on all 20 validation configs, at
    # 17-28 s against 183-252 s (docs/planning.md, "Local search after the beam")
    final: int = 24
    prefix_samples: int = 16  # samples per child sequence in the prefix searches
    prefix_iterations: int = 30  # iterations of each prefix search
    # as exhaustive's: 0: only sequences of the problem's horizon H; N > 0: every complete sequence of
    # 1..N steps is a candidate (ignored when the problem gives a skeleton)
    max_horizon: int = 0
    # local search after the final search (no given skeleton): up to `polish` rounds, each searching every
    # valid sequence one edit away from the `polish_top` best found so far (0: off); it recovers the push-first
    # and longer plans the beam drops on noisy prefix values
    polish: int = 3
    polish_top: int = 2
    # each sequence draws from its own stream: a sequence scores alike whichever others are searched beside
    # it, so the beam, the final search and the local search compare sequences, not draws (docs/planning.md)
    draws: str = "sequence"

    def __post_init__(self) -> None:
        super().__post_init__()
        from pasta.config import MAX_HORIZON
        from pasta.config.validate import check_int

        check_int(self.width, "planner.width", low=1)
        check_int(self.final, "planner.final", low=1)
        check_int(self.window, "planner.window", low=1, high=MAX_HORIZON)
        check_int(self.prefix_samples, "planner.prefix_samples", low=1)
        check_int(self.prefix_iterations, "planner.prefix_iterations", low=0)
        check_int(self.max_horizon, "planner.max_horizon", low=0, high=MAX_HORIZON)
        check_int(self.polish, "planner.polish", low=0)
        check_int(self.polish_top, "planner.polish_top", low=1)
