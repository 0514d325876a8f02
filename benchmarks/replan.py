"""Plan (no execution) task instances with one or more planners and print the plan objective side by side.

    python benchmarks/replan.py --task crs --horizon 6 --seeds 1000 1001 1002 \
        --planner prefix_beam --planner "exhaustive planner.max_horizon=6" [--skeleton task] [--skills cut,push,roll] \
        [--reference docs/results/crs_pasta_h6.jsonl]

Each ``--planner`` is a planner name followed by ``planner.KEY=VALUE`` overrides. The problem is built as
``pasta eval`` builds it (shipped weights, the task's skills with weights, the episode seed), so the
scores are the ``plan_score`` an evaluation would record. ``--reference`` adds the ``plan_score`` /
``plan_s`` / skeleton of an earlier evaluation's rows for the same seeds (what was measured then).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--task", default="crs")
    ap.add_argument("--horizon", type=int, default=0)
    ap.add_argument("--seeds", type=int, nargs="+", default=[1000])
    ap.add_argument("--planner", action="append", default=[], help='"NAME planner.k=v ..." (repeatable)')
    ap.add_argument("--skeleton", default="", help="skeleton= of the run config: a,b,c, task, or empty (the planner searches)")
    ap.add_argument("--skills", default="", help="comma-separated skills to plan with (default: the task's default set)")
    ap.add_argument("--reference", default="")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--json", default="", help="also write the rows here (JSON lines)")
    ap.add_argument("--seed-offset", type=int, default=0,
                    help="plan with seed + this: another draw of the point subsampling and of the planner's "
                         "samples, for the run-to-run spread (0: as `pasta eval` plans)")
    args = ap.parse_args(argv)
    import torch

    torch.set_num_threads(args.threads)
    from pasta.execute.session import build_session

    ref = {}
    if args.reference:
        for line in Path(args.reference).read_text().splitlines():
            if line.strip():
                row = json.loads(line)
                ref[int(row["seed"])] = row
    planners = args.planner or ["prefix_beam"]
    sessions = []
    for spec in planners:
        name, *over = spec.split()
        given = [f"planner={name}", *over, f"skeleton={args.skeleton}", *([f"horizon={args.horizon}"] if args.horizon else []),
                 *([f"skills={args.skills}"] if args.skills else [])]
        sessions.append((spec, build_session(args.task, given)))
    sim = sessions[0][1].task.make_sim()
    print(f"| seed | planner | plan score | plan s | skeleton |")
    print("|---:|---|---:|---:|---|")
    rows = []
    for seed in args.seeds:
        if seed in ref:
            r = ref[seed]
            print(f"| {seed} | reference ({Path(args.reference).stem}) | {r['plan_score']:.4f} | {r['plan_s']:.1f} | "
                  f"{'-'.join(r['skeleton'])} |", flush=True)
        for spec, session in sessions:
            t0 = time.perf_counter()
            plan = session.plan(seed, sim=sim, planning_seed=seed + args.seed_offset).plan
            wall = time.perf_counter() - t0
            print(f"| {seed} | {spec} | {plan.score:.4f} | {wall:.1f} | {'-'.join(plan.skills)} |", flush=True)
            rows.append({"seed": seed, "planner": spec, "score": plan.score, "plan_s": wall, "skeleton": list(plan.skills),
                         "horizon": session.horizon, "task": args.task, "seed_offset": args.seed_offset,
                         "skills": [s.name for s in session.skills]})
            if args.json:  # after every plan: a killed run keeps what it measured
                Path(args.json).write_text("".join(json.dumps(r) + "\n" for r in rows))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
