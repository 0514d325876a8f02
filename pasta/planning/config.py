"""Settings shared by the latent-optimising planners (paper defaults in comments; each default is the setting
behind the shipped results, docs/planning.md)."""

from __future__ import annotations

from dataclasses import dataclass, field

from pasta.core import PluginConfig

#: how a search draws attention (LatentPlannerConfig.attention; "enumerate" is the paper's "no sampling" ablation)
ATTENTION_MODES = ("sample", "enumerate")
#: where a search's candidates come from (LatentPlannerConfig.draws)
DRAW_MODES = ("shared", "sequence")


@dataclass
class LatentPlannerConfig(PluginConfig):
    """Plans are scored by ``prod_h max(f_h, 0.01) * exp(-cost_weight * C)``; see :mod:`pasta.planning.objective`.

    ``num_samples`` counts attention + sub-goal samples *per skill sequence*; a search over ``S``
    sequences optimises ``S * num_samples`` samples in one batch.
    """

    # Attention + sub-goal samples per skill sequence. The paper used 5000 on a GPU; on a 2-core CPU the
    # score plateaus far earlier (docs/planning.md: ~50 per sequence for crs with random networks; the
    # analytic test problem needs ~128), so the default is sized for a CPU.
    num_samples: int = 128
    # How attention is drawn: "sample" (each candidate draws its own, num_samples per sequence) or "enumerate"
    # (every attention structure of a sequence, num_samples latent draws each). With num_samples=1 and
    # refine_sequences=0, "enumerate" is the paper's "no sampling" ablation: one initialisation per structure.
    attention: str = "sample"
    # Where the candidates' random draws come from: "shared" (one stream for the whole search, sequence
    # after sequence) or "sequence" (each sequence its own stream, seeded by the problem's seed, the skill
    # names and the search round). With "sequence" a sequence's result does not depend on which other
    # sequences are searched beside it, so two planners that both reach a sequence give it the same
    # candidates: their scores differ only by the sequences they reach, not by the luck of the draw
    # (docs/planning.md, "Common draws"; prefix_beam's default). CEM's redraws stay on the shared stream.
    draws: str = "shared"
    iterations: int = 100  # optimiser iterations (paper 100-300); the last one only evaluates
    # Adam learning rate on the sub-goal latents. The paper used 0.01; with our VAE latents and 100 iterations
    # 0.05 found the right crs skeleton on 4/4 test configs against 0/4 at 0.01 (docs/planning.md).
    lr: float = 0.05
    # Adam's epsilon. torch's 1e-8 swamps the tiny gradients of nearly infeasible steps; a small epsilon
    # lets Adam follow them at full step size.
    adam_eps: float = 1e-20
    cost_weight: float = 100.0  # lambda (paper: 100 for CRS-type tasks, 10 otherwise)
    # Clearance: add this times the path-overlap penalty of pieces moved through other pieces to the plan
    # cost (pasta.planning.clearance; 0 disables, the paper has no such term). One full overlap then costs
    # cost_weight * clearance_weight = 5 in log score, like a step at feasibility e^-5.
    clearance_weight: float = 0.05
    keep_per_sequence: int = 4  # also: candidates per sequence reported in plan.info (paper top-4)
    # Refinement: after the search, the best `refine_sequences` sequences are searched once more with
    # fresh `num_samples` candidates each, and every sequence keeps the better of its two results
    # (0 disables; skipped when the search had no more sequences than this). One sequence's best of 128
    # samples varies by a few hundredths of plan score from draw to draw, as much as the gap between the
    # right and the wrong skeleton of crs with distractors (docs/planning.md, "Refining the best sequences").
    refine_sequences: int = 2

    def __post_init__(self) -> None:
        """Range checks, run whenever the section is resolved (every command), naming ``planner.<key>``."""
        from pasta.config.validate import check_choice, check_int, check_number

        check_int(self.num_samples, "planner.num_samples", low=1)
        check_int(self.iterations, "planner.iterations", low=0)
        check_int(self.keep_per_sequence, "planner.keep_per_sequence", low=1)
        check_int(self.refine_sequences, "planner.refine_sequences", low=0)
        # a NaN or zero step size gives NaN latents or no search at all (issue 21: lr=nan planned NaN sub-goals)
        check_number(self.lr, "planner.lr", low=0.0, low_open=True)
        check_number(self.adam_eps, "planner.adam_eps", low=0.0, low_open=True)
        for key in ("cost_weight", "clearance_weight"):
            check_number(getattr(self, key), f"planner.{key}", low=0.0)
        check_choice(self.attention, "planner.attention", ATTENTION_MODES)
        check_choice(self.draws, "planner.draws", DRAW_MODES)


@dataclass
class HalvingConfig(LatentPlannerConfig):
    """Adds successive halving (gradient planners only; the sampling planner has no such fields)."""

    # Successive halving: at these fractions of the iterations keep the better half of every sequence's
    # samples, ranked by the log of the unfloored score (sum_h log f_h - lambda * C); each sequence always
    # keeps its best `keep_per_sequence`. An empty list keeps every sample to the end (crs, 600 samples:
    # 33.0 s without halving, 18.6 s with it, the same score; docs/planning.md).
    halving_points: list[float] = field(default_factory=lambda: [0.1, 0.2, 0.35, 0.5])

    def __post_init__(self) -> None:
        from pasta.config.validate import check_number

        super().__post_init__()
        for i, point in enumerate(self.halving_points):
            check_number(point, f"planner.halving_points[{i}]", low=0.0, high=1.0, low_open=True, high_open=True)
