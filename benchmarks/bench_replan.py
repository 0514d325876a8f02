"""What a closed-loop re-plan costs against one plan of the remaining horizon, from the same observation.

    .venv/bin/python benchmarks/bench_replan.py [--tasks crs,cut_rearrange] [--kinds shift,split,merge]
                                               [--seeds 1000-1004]

For each task, disturbance and seed it plans the episode, executes it with ``execute.loop=closed`` and the
disturbance, and at every re-plan the closed loop asks for, times two plans from the observation the loop saw:
the warm-started re-plan (the remaining skill sequence, then if needed its one-step extensions,
:func:`pasta.execute.episode.replanner`; stage 2 when the re-plan is not the remaining sequence) and a plain plan of the remaining horizon (every sequence of that
length). Prints one row per re-plan and the totals; torch on one thread, as ``pasta eval`` runs.
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def seeds_arg(text: str) -> list[int]:
    if "-" in text:
        lo, hi = (int(v) for v in text.split("-"))
        return list(range(lo, hi + 1))
    return [int(v) for v in text.split(",")]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tasks", default="crs,cut_rearrange")
    parser.add_argument("--kinds", default="shift,split,merge")
    parser.add_argument("--seeds", default="1000-1004")
    args = parser.parse_args()
    import torch

    from pasta.execute.episode import perceive_and_plan, replanner
    from pasta.execute.executor import execute_plan
    from pasta.execute.loop import remaining_skills
    from pasta.execute.session import build_session

    torch.set_num_threads(1)
    rows = []
    for task in args.tasks.split(","):
        for kind in args.kinds.split(","):
            session = build_session(overrides=[f"task={task}", "execute.loop=closed", f"disturb={kind}", "threads=1"])
            sim = session.task.make_sim()
            plan_args = {"planner": session.planner, "skills": session.skills, "encoder": session.encoder,
                         "cost": session.cost, "perception": session.perception, "check": session.check,
                         "planner_name": session.planner_name}
            for seed in seeds_arg(args.seeds):
                inst = session.task.instance(seed)
                sim.set_state(inst.init)
                first = perceive_and_plan(sim.observe().dough, inst.goal, horizon=session.horizon, seed=seed,
                                          skeleton=session.skeleton(inst), **plan_args).plan
                warm = replanner(inst.goal, seed=seed, **plan_args)

                def timed(dough, plan, executed, labels, task=task, kind=kind, seed=seed, warm=warm, inst=inst,
                          plan_args=plan_args):
                    remaining = remaining_skills(plan, executed)
                    t0 = time.perf_counter()
                    new = warm(dough, plan, executed, labels)
                    t1 = time.perf_counter()
                    full = perceive_and_plan(dough, inst.goal, horizon=len(remaining), seed=seed, obs_labels=labels,
                                             **plan_args).plan
                    t2 = time.perf_counter()
                    rows.append({"task": task, "kind": kind, "seed": seed, "remaining": len(remaining),
                                 "stage": 1 if new.skills == remaining else 2, "warm_s": t1 - t0,
                                 "full_s": t2 - t1, "warm_cost": new.final_cost, "full_cost": full.final_cost,
                                 "new": "-".join(new.skills)})
                    r = rows[-1]
                    print(f"{task:<14} {kind:<6} {seed}  remaining {r['remaining']}  warm {r['warm_s']:5.1f} s "
                          f"(stage {r['stage']}: {r['new']})  full plan {r['full_s']:5.1f} s", flush=True)
                    return new

                execute_plan(sim, first, skills={s.name: s for s in session.skills}, encoder=session.encoder,
                             goal=inst.goal, cfg=session.exe, perception=session.perception,
                             emd_points=session.task.config.emd_points, emd_seed=session.task.config.emd_seed,
                             disturb=kind, seed=seed, replan=timed)
    if not rows:
        print("no re-plan happened")
        return
    print()
    print("| task | re-plans | warm re-plan s (mean, max) | plan of the remaining horizon s (mean, max) | warm / full |")
    print("|---|---:|---:|---:|---:|")
    for task in dict.fromkeys(r["task"] for r in rows):
        sub = [r for r in rows if r["task"] == task]
        w, f = np.array([r["warm_s"] for r in sub]), np.array([r["full_s"] for r in sub])
        print(f"| {task} | {len(sub)} | {w.mean():.1f}, {w.max():.1f} | {f.mean():.1f}, {f.max():.1f} | "
              f"{w.sum() / f.sum():.2f} |")


if __name__ == "__main__":
    main()
