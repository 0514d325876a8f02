"""Planning time and final score vs number of samples on the CRS structure.

CRS: 1 observed entity -> 2 goal entities in 3 steps with cut (1 -> 2), push (1 -> 1), roll (1 -> 1):
12 skill sequences, latent ``D = 5``. Feasibility per skill is :class:`pasta.nn.feasibility.SetFeasibility`
and the cost :class:`pasta.nn.cost.PairCost`; trained ones from ``--models DIR`` when given, otherwise
randomly initialised networks of the paper's width (hidden 1024, ``--hidden``). ``--samples`` counts
samples over all 12 sequences (``planner.num_samples = samples // 12``).

    .venv/bin/python benchmarks/bench_planner.py                      # table + docs/planning_bench.png
    .venv/bin/python benchmarks/bench_planner.py --samples 500 5000 --iterations 100 --hidden 256

``--scaling``: planning time and score against the horizon (``--horizons``, default 3..8) and the number
of skills (``--skills``: 3 = cut, push, roll; 5 = also lift 1 -> 1 and gather 3 -> 1), 1 -> 2 entities,
sequences of exactly H steps, for ``exhaustive`` and ``prefix_beam`` side by side (``--samples-per-seq``
samples per sequence for both final searches). An exhaustive point whose predicted time (the last
measured time scaled by the growth of the number of sequences) exceeds ``--budget`` seconds is not run
and is marked in the table; the fitted growth is printed at the end.

    .venv/bin/python benchmarks/bench_planner.py --scaling --threads 1 --plot docs/planning_scaling.png
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import torch

from pasta.core import Encoder, PlanningProblem, Skill, SkillSpec
from pasta.plugins import get_plugins
from pasta.testing import configured

SPECS = [SkillSpec("cut", 1, 2, "knife"), SkillSpec("push", 1, 1, "pusher"), SkillSpec("roll", 1, 1, "roller")]
#: the two further registered skills (LiftSpread / GatherMove issue): their cardinalities, for --scaling
EXTRA_SPECS = [SkillSpec("lift", 1, 1, "spatula"), SkillSpec("gather", 3, 1, "gripper")]


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


def build_problem(models: str | None, hidden: int, seed: int = 0, *, specs=None, horizon: int = 3) -> tuple[PlanningProblem, str]:
    skills = [_skill(s) for s in (specs or SPECS)]
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
    return PlanningProblem(obs, goal, skills, encoder, cost, horizon=horizon, seed=seed), what


def run(problem: PlanningProblem, planner: str, samples: int, **overrides) -> dict:
    per_seq = max(1, samples // len(problem.skeletons()))
    p = configured(get_plugins().planners, planner, {"num_samples": per_seq, **overrides})
    t = time.perf_counter()
    plan = p.plan(problem)
    return {"time": time.perf_counter() - t, "score": plan.score, "cost": plan.final_cost, "skills": "-".join(plan.skills),
            "evals": plan.info["evaluations"], "samples": plan.info["samples"], "optimise": plan.timings["optimise"]}


def scaling(args) -> None:
    """Time and score vs horizon and number of skills, exhaustive against prefix_beam (same final search)."""
    from pasta.core import enumerate_skeletons

    results = []  # (planner, K, H, row or None, note)
    print(f"# scaling: 1 -> 2 entities, sequences of exactly H steps, {args.iterations} iterations, "
          f"{args.samples_per_seq} samples per sequence in the final search, successive halving on, clearance off, "
          f"budget {args.budget:.0f} s per exhaustive point, torch {torch.__version__}, {torch.get_num_threads()} threads")
    header = "| planner | K | H | sequences | time s | score | best sequence | note |"
    print(header)
    print("|---|---:|---:|---:|---:|---:|---|---|")
    for k in args.skills:
        specs = (SPECS + EXTRA_SPECS)[:k]
        last = None  # (sequences, seconds) of the last exhaustive point measured
        for h in args.horizons:
            problem, what = build_problem(args.models, args.hidden, args.seed, specs=specs, horizon=h)
            n_seq = len(enumerate_skeletons([s.spec for s in problem.skills], h, 1, 2))
            for planner in ("exhaustive", "prefix_beam"):
                # clearance_weight 0: the prior-only encoder cannot decode the extents the penalty needs
                over = {"num_samples": args.samples_per_seq, "iterations": args.iterations, "clearance_weight": 0.0}
                note = ""
                if planner == "exhaustive" and last is not None and last[1] * n_seq / last[0] > args.budget:
                    note = f"not run: predicted {last[1] * n_seq / last[0]:.0f} s > budget"
                    print(f"| {planner} | {k} | {h} | {n_seq} | | | | {note} |", flush=True)
                    results.append((planner, k, h, None, note))
                    continue
                p = configured(get_plugins().planners, planner, over)
                t = time.perf_counter()
                plan = p.plan(problem)
                r = {"time": time.perf_counter() - t, "score": plan.score, "skills": "-".join(plan.skills)}
                if planner == "exhaustive":
                    last = (n_seq, r["time"])
                else:
                    note = f"{plan.info['beam']['prefix_searches']} prefix searches, final over {plan.info['sequences']}"
                print(f"| {planner} | {k} | {h} | {n_seq} | {r['time']:.1f} | {r['score']:.4f} | {r['skills']} | {note} |",
                      flush=True)
                results.append((planner, k, h, r, note))
    report(results, args)


def report(results, args) -> None:
    """Fitted growth of the time with H and the PNG, from ``(planner, K, H, row or None, note)`` rows."""
    skills = sorted({r[1] for r in results})
    import numpy as np

    print()
    for planner in ("exhaustive", "prefix_beam"):
        for k in skills:
            pts = [(h, r["time"]) for p, kk, h, r, _ in results if p == planner and kk == k and r]
            if len(pts) >= 2:
                hs, ts = np.array([p[0] for p in pts], float), np.array([p[1] for p in pts], float)
                a = np.polyfit(np.log(hs), np.log(ts), 1)[0]  # time ~ H^a
                b = np.polyfit(hs, np.log(ts), 1)[0]  # time ~ e^(b H)
                print(f"{planner}, K={k}: time ~ H^{a:.2f} (log-log fit) or ~ {np.exp(b):.2f}^H (log-linear fit), "
                      f"H = {int(hs[0])}..{int(hs[-1])}")
    if args.plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, (a, b) = plt.subplots(1, 2, figsize=(10, 4))
        for planner, style in (("exhaustive", "s--"), ("prefix_beam", "o-")):
            for k in skills:
                pts = [(h, r) for p, kk, h, r, _ in results if p == planner and kk == k and r]
                if pts:
                    a.plot([p[0] for p in pts], [p[1]["time"] for p in pts], style, label=f"{planner}, K={k}")
                    b.plot([p[0] for p in pts], [p[1]["score"] for p in pts], style, label=f"{planner}, K={k}")
        a.set_yscale("log")
        for ax, name in ((a, "planning time (s)"), (b, "plan score")):
            ax.set_xlabel("horizon H")
            ax.set_ylabel(name)
            ax.grid(True, alpha=0.3)
        b.legend(fontsize=8)
        fig.suptitle(f"exhaustive vs prefix_beam, random networks hidden {args.hidden}; missing exhaustive points: "
                     f"over the {args.budget:.0f} s budget", fontsize=9)
        fig.tight_layout()
        Path(args.plot).parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(args.plot, dpi=100)
        print(f"plot written to {args.plot}")


def replot(path: str, args) -> None:
    """Rebuild the fit and the PNG from the table a ``--scaling`` run printed (e.g. one cut short)."""
    results = []
    for line in Path(path).read_text().splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 8 and cells[0] in ("exhaustive", "prefix_beam"):
            row = {"time": float(cells[4]), "score": float(cells[5]), "skills": cells[6]} if cells[4] else None
            results.append((cells[0], int(cells[1]), int(cells[2]), row, cells[7]))
    report(results, args)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--samples", type=int, nargs="+", default=[500, 1000, 2000, 5000])
    ap.add_argument("--no-halving-max", type=int, default=2000, help="largest sample count also run without halving")
    ap.add_argument("--iterations", type=int, default=100)
    ap.add_argument("--hidden", type=int, default=1024)
    ap.add_argument("--models", default=None, help="directory of trained models (pasta.nn layout)")
    ap.add_argument("--threads", type=int, default=0)
    ap.add_argument("--extra", action="store_true", help="also run the sampling planner")
    ap.add_argument("--plot", default="docs/planning_bench.png")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--replot", default="", help="--scaling only: fit and plot the table of an earlier run's output")
    ap.add_argument("--scaling", action="store_true", help="time and score vs horizon and number of skills")
    ap.add_argument("--horizons", type=int, nargs="+", default=[3, 4, 5, 6, 7, 8])
    ap.add_argument("--skills", type=int, nargs="+", default=[3, 5], choices=[3, 4, 5])
    ap.add_argument("--samples-per-seq", type=int, default=32)
    ap.add_argument("--budget", type=float, default=300.0, help="seconds: skip exhaustive points predicted longer")
    args = ap.parse_args()
    if args.threads:
        torch.set_num_threads(args.threads)
    if args.replot:
        if args.plot == "docs/planning_bench.png":
            args.plot = "docs/planning_scaling.png"
        replot(args.replot, args)
        return
    if args.scaling:
        if args.plot == "docs/planning_bench.png":
            args.plot = "docs/planning_scaling.png"
        scaling(args)
        return
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
            emit("exhaustive", n, run(problem, "exhaustive", n, iterations=args.iterations, halving_points=[]))
        emit("exhaustive + successive halving", n, run(problem, "exhaustive", n, iterations=args.iterations))
    if args.extra:
        n = args.samples[0]
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
