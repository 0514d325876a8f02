"""Plan crs scenes with 0..N extra pieces that already sit at their goal pieces (plan only; a table).

    python benchmarks/distractor_scaling.py --seeds 1000-1009 --counts 0 1 2 4 6 [--before] [--out runs/scaling.jsonl]

Scenes come from the crs_distractors test instances (2 distractors each): the observed and goal clouds
with the distractor pieces taken out (0), one kept (1), both (2), or copies of both (same particles,
translated to free spots near the front/back walls, identically in the observation and the goal) added
(4, 6). Each scene is planned with the default `pasta` planner and shipped weights, as `pasta run` plans
(`pasta.execute.episode.perceive_and_plan`); `--before` also plans it with the unchanged-entity
matching off (`unchanged_threshold=0`, the planner before issue 22). Nothing is executed: the scenes
with copied pieces have no simulator state. Printed per count: right skeleton (the task's
cut-push-roll), plans attending a distractor, plan score, planning seconds and the attention
structures of cut-push-roll (`prod_h C(K_h - F, N_h)`, F = pieces kept out).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np


def seeds_arg(text: str) -> list[int]:
    lo, _, hi = text.partition("-")
    return list(range(int(lo), int(hi or lo) + 1))


def scene(obs: np.ndarray, goal: np.ndarray, count: int) -> tuple[np.ndarray, np.ndarray, int]:
    """The ``(obs, goal)`` clouds with ``count`` distractors (see the module docstring) and how many were found."""
    from pasta.core.decompose import decompose_labels
    from pasta.core.matching import unchanged_pairs
    from pasta.core.metrics import sample_points

    lo, lg = decompose_labels(obs), decompose_labels(goal)
    po = [obs[lo == e] for e in range(lo.max() + 1)]
    pg = [goal[lg == e] for e in range(lg.max() + 1)]
    rng = np.random.default_rng(0)
    pairs = unchanged_pairs(np.stack([sample_points(p, 500, rng) for p in po]),
                            np.stack([sample_points(p, 500, rng) for p in pg]))
    dis = [(po[i], pg[j]) for i, j in pairs]
    base_o = [p for i, p in enumerate(po) if i not in {i for i, _ in pairs}]
    base_g = [p for j, p in enumerate(pg) if j not in {j for _, j in pairs}]
    chosen = dis[:count]
    pieces = base_o + base_g + [a for a, _ in chosen] + [b for _, b in chosen]
    spots = [(x, z) for x in (0.2, 0.8, 0.5, 0.35, 0.65) for z in (0.13, 0.87)]
    k = 0
    while len(chosen) < count:
        if k >= len(spots):
            raise RuntimeError(f"no free spot left for distractor {len(chosen) + 1}")
        x, z = spots[k]
        k += 1
        a, b = dis[len(chosen) % len(dis)]
        shift = np.array([x, 0.0, z]) - np.array([a[:, 0].mean(), 0.0, a[:, 2].mean()])
        a2, b2 = a + shift, b + shift
        gap = min(np.min(np.abs(p[:, [0, 2]][:, None] - a2[None, :, [0, 2]]).max(-1)) for p in pieces)
        if gap < 0.06:  # keep pieces 6 cm apart (DBSCAN eps is 3 cm)
            continue
        chosen.append((a2, b2))
        pieces += [a2, b2]
    return (np.concatenate(base_o + [a for a, _ in chosen]).astype(np.float32),
            np.concatenate(base_g + [b for _, b in chosen]).astype(np.float32), len(dis))


def attended_origins(plan, k0: int) -> set[int]:
    origin: list = list(range(k0))
    out = set()
    for step in plan.steps:
        out |= {origin[i] for i in step.inputs if origin[i] is not None}
        origin = [None] * len(step.subgoal) + [origin[i] for i in range(len(origin)) if i not in step.inputs]
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=seeds_arg, default=seeds_arg("1000-1009"))
    ap.add_argument("--counts", type=int, nargs="+", default=[0, 1, 2, 4, 6])
    ap.add_argument("--before", action="store_true", help="also plan with the unchanged-entity matching off")
    ap.add_argument("--out", type=Path, default=Path("runs/distractor_scaling.jsonl"))
    args = ap.parse_args(argv)

    import torch

    torch.set_num_threads(1)
    from pasta.core.decompose import decompose
    from pasta.core.matching import unchanged_pairs
    import dataclasses

    from pasta.execute.episode import perceive_and_plan
    from pasta.execute.session import build_session

    s = build_session("crs_distractors")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    done = set()
    if args.out.exists():
        done = {(r["seed"], r["count"], r["matching"]) for r in map(json.loads, args.out.read_text().splitlines())}
    modes = [("on", 5e-4)] + ([("off", 0.0)] if args.before else [])
    with args.out.open("a") as fh:
        for mode, threshold in modes:
            for count in args.counts:
                for seed in args.seeds:
                    if (seed, count, mode) in done or (mode == "off" and count == 0):
                        continue  # nothing to keep out with no distractor: the same plan
                    inst = s.task.instance(seed)
                    sim = s.task.make_sim()
                    sim.set_state(inst.init)
                    obs, goal, found = scene(sim.observe().dough, inst.goal, count)
                    eo = decompose(obs, min_points=50, seed=seed)
                    eg = decompose(goal, min_points=50, seed=seed)
                    fixed = unchanged_pairs(np.stack(eo), np.stack(eg))
                    t0 = time.perf_counter()
                    plan = perceive_and_plan(obs, goal, planner=s.planner, skills=s.skills, encoder=s.encoder, cost=s.cost,
                                             horizon=3, seed=seed, check=s.check, perception=dataclasses.replace(
                                                 s.perception, unchanged_threshold=threshold)).plan
                    wall = time.perf_counter() - t0
                    k, f = len(eo), len(fixed) if threshold > 0 else 0
                    structures = math.prod(math.comb(kk - f, 1) for kk in (k, k + 1, k + 1))
                    row = {"seed": seed, "count": count, "matching": mode, "entities": k, "goal_entities": len(eg),
                           "fixed": len(fixed), "skeleton": list(plan.skills), "right": list(plan.skills) == ["cut", "push", "roll"],
                           "attends_distractor": bool(attended_origins(plan, k) & {i for i, _ in fixed}),
                           "score": plan.score, "plan_s": float(plan.timings["total"]), "wall_s": wall,
                           "structures_cpr": structures}
                    fh.write(json.dumps(row) + "\n")
                    fh.flush()
                    print(json.dumps(row), flush=True)
    table(args.out)
    return 0


def table(path: Path) -> None:
    rows = [json.loads(line) for line in path.read_text().splitlines()]
    print("| distractors | matching | plans | right skeleton | attends a distractor | plan score | plan s | structures (cut-push-roll) |")
    print("|---:|---|---:|---:|---:|---:|---:|---:|")
    for count in sorted({r["count"] for r in rows}):
        for mode in ("on", "off"):
            rs = [r for r in rows if r["count"] == count and r["matching"] == mode]
            if not rs:
                continue
            sc = np.array([r["score"] for r in rs])
            print(f"| {count} | {mode} | {len(rs)} | {sum(r['right'] for r in rs)}/{len(rs)} | "
                  f"{sum(r['attends_distractor'] for r in rs)}/{len(rs)} | {sc.mean():.3f} ± {sc.std():.3f} | "
                  f"{np.mean([r['plan_s'] for r in rs]):.1f} | {rs[0]['structures_cpr']} |")


if __name__ == "__main__":
    sys.exit(main())
