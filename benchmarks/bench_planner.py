"""Planning time and final score vs number of samples on the CRS structure.

CRS: 1 observed entity -> 2 goal entities in 3 steps with cut (1 -> 2), push (1 -> 1), roll (1 -> 1):
12 skill sequences, latent ``D = 5``. Feasibility per skill is :class:`pasta.nn.feasibility.SetFeasibility`
and the cost :class:`pasta.nn.cost.PairCost`; trained ones from ``--models DIR`` when given, otherwise
randomly initialised networks of the paper's width (hidden 1024, ``--hidden``). ``--samples`` counts
samples over all 12 sequences (``planner.num_samples = samples // 12``).

    .venv/bin/python benchmarks/bench_planner.py                      # table + docs/planning_bench.png
    .venv/bin/python benchmarks/bench_planner.py --samples 500 5000 --iterations 100 --hidden 256
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import torch

from pasta.core import Encoder, PlanningProblem, Skill, SkillSpec
from pasta.plugins import get_plugins
from pasta.plugins.checks import configured

SPECS = [SkillSpec("cut", 1, 2, "knife"), SkillSpec("push", 1, 1, "pusher"), SkillSpec("roll", 1, 1, "roller")]


class PriorEncoder(Encoder):
    """Prior and centroid box only (the planner never decodes): z ~ N(0, 1), t uniform in the CRS box."""

    z_dim = 2
    t_low = (0.1, 0.0, 0.1)
    t_high = (0.9, 0.15, 0.9)

    def encode(self, points):  # pragma: no cover - not used by planning
        raise NotImplementedError

    def decode(self, latents, num_points):  # pragma: no cover
        raise NotImplementedError

    def sample_prior(self, n, generator):
        z = torch.randn(n, self.z_dim, generator=generator)
        low, high = torch.tensor(self.t_low), torch.tensor(self.t_high)
        return torch.cat([z, low + torch.rand(n, 3, generator=generator) * (high - low)], -1)


def _scaled_cost_class():
    from pasta.nn.cost import SetCostModel

    class ScaledCost(SetCostModel):
        """Random :class:`PairCost` scaled to Chamfer magnitudes (x 1e-3), so ``exp(-100 C)`` is informative."""

        def pairwise(self, a, b):
            return super().pairwise(a, b) * 1e-3

    return ScaledCost


def _skill(spec: SkillSpec) -> Skill:
    return type(f"Bench_{spec.name}", (Skill,), {"spec": spec})()


def build_problem(models: str | None, hidden: int, seed: int = 0) -> tuple[PlanningProblem, str]:
    skills = [_skill(s) for s in SPECS]
    if models:
        from pasta.nn.loading import load_models

        encoder, cost = load_models(models, skills)
        what = f"trained networks from {models}"
        gen = torch.Generator().manual_seed(seed)
        obs, goal = encoder.sample_prior(1, gen), encoder.sample_prior(2, gen)
    else:
        from pasta.nn.cost import PairCost

        ScaledCost = _scaled_cost_class()
        from pasta.nn.feasibility import SetFeasibility

        torch.manual_seed(seed)
        for s in skills:
            s.attach_feasibility(SetFeasibility(s.n_in, s.n_out, 5, hidden=hidden).eval().requires_grad_(False))
        cost = ScaledCost(model=PairCost(5, hidden=hidden).requires_grad_(False))
        encoder = PriorEncoder()
        gen = torch.Generator().manual_seed(seed)
        obs, goal = encoder.sample_prior(1, gen), encoder.sample_prior(2, gen)
        what = f"randomly initialised pasta.nn networks, hidden {hidden} (no trained weights given; cost x 1e-3)"
    return PlanningProblem(obs, goal, skills, encoder, cost, horizon=3, seed=seed), what


def run(problem: PlanningProblem, planner: str, samples: int, **overrides) -> dict:
    per_seq = max(1, samples // len(problem.skeletons()))
    p = configured(get_plugins().planners, planner, {"num_samples": per_seq, **overrides})
    t = time.perf_counter()
    plan = p.plan(problem)
    return {"time": time.perf_counter() - t, "score": plan.score, "cost": plan.final_cost, "skills": "-".join(plan.skills),
            "evals": plan.info["evaluations"], "samples": plan.info["samples"], "optimise": plan.timings["optimise"]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--samples", type=int, nargs="+", default=[500, 1000, 2000, 5000])
    ap.add_argument("--no-halving-max", type=int, default=2000, help="largest sample count also run without halving")
    ap.add_argument("--iterations", type=int, default=100)
    ap.add_argument("--hidden", type=int, default=1024)
    ap.add_argument("--models", default=None, help="directory of trained models (pasta.nn layout)")
    ap.add_argument("--threads", type=int, default=0)
    ap.add_argument("--extra", action="store_true", help="also compare matching modes and the sampling planner")
    ap.add_argument("--plot", default="docs/planning_bench.png")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    if args.threads:
        torch.set_num_threads(args.threads)
    problem, what = build_problem(args.models, args.hidden, args.seed)
    print(f"# CRS structure, {len(problem.skeletons())} sequences, {args.iterations} iterations, {what}, "
          f"torch {torch.__version__}, {torch.get_num_threads()} threads")
    rows = []
    header = f"| {'planner':<34} | {'samples':>7} | {'sample-iters':>12} | {'time s':>7} | {'score':>9} | {'cost':>8} | best sequence |"
    print(header)
    print("|" + "|".join("-" * (len(c)) for c in header.split("|")[1:-1]) + "|")

    def emit(label, samples, r):
        rows.append((label, samples, r))
        print(f"| {label:<34} | {r['samples']:>7} | {r['evals']:>12} | {r['time']:>7.1f} | {r['score']:>9.3e} | {r['cost']:>8.5f} | {r['skills']} |", flush=True)

    for n in args.samples:
        if n <= args.no_halving_max:
            emit("exhaustive", n, run(problem, "exhaustive", n, iterations=args.iterations))
        emit("exhaustive + successive halving", n, run(problem, "exhaustive", n, iterations=args.iterations, successive_halving=True))
    if args.extra:
        n = args.samples[0]
        emit("exhaustive, matching=recompute", n, run(problem, "exhaustive", n, iterations=args.iterations, matching="recompute"))
        emit("sampling (CEM, no gradient)", n, run(problem, "sampling", n, iterations=args.iterations))
    if args.plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, (a, b) = plt.subplots(1, 2, figsize=(10, 4))
        for label in dict.fromkeys(r[0] for r in rows):
            pts = [(r[2]["samples"], r[2]) for r in rows if r[0] == label]
            if len(pts) < 2 and "," in label:
                continue
            xs = [p[0] for p in pts]
            a.plot(xs, [p[1]["time"] for p in pts], "o-", label=label)
            b.plot(xs, [p[1]["score"] for p in pts], "o-", label=label)
        for ax, name in ((a, "planning time (s)"), (b, "final plan score")):
            ax.set_xscale("log")
            ax.set_xlabel("samples (all 12 sequences)")
            ax.set_ylabel(name)
            ax.grid(True, alpha=0.3)
        a.axhline(30, color="grey", ls="--", lw=1)
        b.legend(fontsize=8)
        fig.suptitle("pasta planner on the CRS structure (" + what.split(",")[0] + ")", fontsize=9)
        fig.tight_layout()
        Path(args.plot).parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(args.plot, dpi=100)
        print(f"plot written to {args.plot}")


if __name__ == "__main__":
    main()
