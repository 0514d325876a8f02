"""Settings shared by the latent-optimising planners (paper defaults in comments)."""

from __future__ import annotations

from dataclasses import dataclass, field

from pasta.core import PluginConfig

#: how a search draws attention (LatentPlannerConfig.attention)
ATTENTION_MODES = ("sample", "enumerate")
#: where a search's candidates come from (LatentPlannerConfig.draws)
DRAW_MODES = ("shared", "sequence")


@dataclass
class LatentPlannerConfig(PluginConfig):
    """Plans are scored by ``prod_h f_h * exp(-cost_weight * C)``; see :mod:`pasta.planning.objective`.

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
    # sequences are searched beside it (halving_scope "sequence"), so two planners that both reach a
    # sequence give it the same candidates: their scores differ only by the sequences they reach, not
    # by the luck of the draw (docs/planning.md, "Common draws"). CEM's redraws stay on the shared stream.
    draws: str = "shared"
    iterations: int = 100  # optimiser iterations (paper 100-300); the last one only evaluates
    # Adam learning rate on the sub-goal latents. The paper used 0.01; with our VAE latents and 100 iterations
    # 0.05 found the right crs skeleton on 4/4 test configs against 0/4 at 0.01 (docs/planning.md).
    lr: float = 0.05
    # Adam's epsilon. torch's 1e-8 swamps the tiny gradients of floored feasibilities (the aux term is
    # there to keep them alive); a small epsilon lets Adam follow them at full step size.
    adam_eps: float = 1e-20
    # What Adam maximises: "log" = sum_h log f_h - cost_weight * C (gradients survive f = 0), or "product" =
    # the paper's prod_h max(f_h, floor) * exp(-cost_weight * C) + aux_weight * sum_h f_h.
    objective: str = "log"
    cost_weight: float = 100.0  # lambda (paper: 100 for CRS-type tasks, 10 otherwise)
    feasibility_floor: float = 0.01  # "product" objective only, and the reported score
    aux_weight: float = 0.01  # "product" objective only
    # Set-cost matching: "recompute" re-solves the minimum-cost matching every iteration (one batched
    # op for <= 4 entities); "frozen" solves it at the first iteration and afterwards evaluates the cost
    # model only on the matched pairs (the paper's choice; 1/G of the cost-model work). "auto": frozen.
    matching: str = "auto"
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
        # the floor is a feasibility, and the reported score multiplies floored feasibilities: outside [0, 1]
        # it is no longer a probability (feasibility_floor=2 reported a "score" of 3.4)
        check_number(self.feasibility_floor, "planner.feasibility_floor", low=0.0, high=1.0)
        for key in ("cost_weight", "aux_weight", "clearance_weight"):
            check_number(getattr(self, key), f"planner.{key}", low=0.0)
        check_choice(self.objective, "planner.objective", ("log", "product"))
        check_choice(self.matching, "planner.matching", ("auto", "frozen", "recompute"))
        check_choice(self.attention, "planner.attention", ATTENTION_MODES)
        check_choice(self.draws, "planner.draws", DRAW_MODES)


@dataclass
class HalvingConfig(LatentPlannerConfig):
    """Adds successive halving (gradient planners only; the sampling planner has no such fields)."""

    # Successive halving: at these fractions of the iterations keep the better half of the samples, ranked
    # by the log of the unfloored score (sum_h log f_h - lambda * C), within each sequence ("sequence")
    # or over all sequences ("global"); each sequence always keeps its best `keep_per_sequence`.
    successive_halving: bool = True
    halving_points: list[float] = field(default_factory=lambda: [0.1, 0.2, 0.35, 0.5])
    halving_scope: str = "sequence"  # "sequence": halve every sequence; "global": rank all samples together

    def __post_init__(self) -> None:
        from pasta.config.validate import check_choice, check_number

        super().__post_init__()
        for i, point in enumerate(self.halving_points):
            check_number(point, f"planner.halving_points[{i}]", low=0.0, high=1.0, low_open=True, high_open=True)
        check_choice(self.halving_scope, "planner.halving_scope", ("sequence", "global"))
