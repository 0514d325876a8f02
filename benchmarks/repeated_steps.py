"""Plans that run a 1 -> 1 skill twice on the same piece, and goal pieces outside the models' workspace.

Plans each seed of ``task`` as ``pasta run`` does (shipped weights or ``models=DIR``; planning only, no
simulation) and reports, per seed:

- ``repeat``: a step that applies a 1 -> 1 skill to the entity the step before produced with the same skill
  (crs_twice: the second roll rolls the piece the first roll rolled, and the other piece is never rolled);
- the goal pieces' centroids and which lie outside the encoder's centroid box (the range of the entities
  it was trained on, where the planner keeps its sub-goals);
- for a repeated last step, the best plan score the last receding-horizon window reaches for each entity it
  could attend instead, with that candidate's feasibility and set cost (``windows=1``; receding planner only);
- with ``truth=1``, how each skill's feasibility network rates the task's own ground-truth steps (the expert
  chain that made the goal: observed pieces before and after each step, encoded as at planning).

::

    python benchmarks/repeated_steps.py task=crs_twice seeds=2000-2019 [models=DIR] [windows=1] [truth=1] \\
        [planner.KEY=VALUE ...]

Prints a line per seed and the counts (docs/planning.md, "crs_twice plans that roll one piece twice").
"""

from __future__ import annotations

import dataclasses
import sys
from typing import Any

import numpy as np
import torch


def parse_seeds(text: str) -> list[int]:
    """``"2000-2019"`` or ``"2000,2003"`` -> seeds."""
    out: list[int] = []
    for part in text.split(","):
        lo, _, hi = part.partition("-")
        out.extend(range(int(lo), int(hi) + 1) if hi else [int(lo)])
    return out


def repeated_steps(plan: Any, skills: dict[str, Any]) -> list[int]:
    """Plan steps ``h`` whose 1 -> 1 skill consumes the entity step ``h - 1`` produced with the same skill
    (a step's outputs are rows ``0 .. M - 1`` of the set after it)."""
    out = []
    for h in range(1, len(plan.steps)):
        prev, step = plan.steps[h - 1], plan.steps[h]
        spec = skills[step.skill].spec
        if step.skill == prev.skill and spec.n_in == spec.n_out == 1 and tuple(step.inputs) == (0,):
            out.append(h)
    return out


def last_window_by_attention(problem: Any, config: Any, start: torch.Tensor,
                             skill: str) -> dict[int, tuple[float, float, float]]:
    """Best score, with its feasibility and set cost, of a one-step window of ``skill`` from ``start (K, D)``
    for each entity it attends (every attention enumerated, 64 latent draws each, no halving)."""
    from pasta.planning.batch import evaluate, sample_candidates
    from pasta.planning.optimizer import _Optimiser

    cfg = dataclasses.replace(config, attention="enumerate", num_samples=64)
    if hasattr(cfg, "successive_halving"):
        cfg = dataclasses.replace(cfg, successive_halving=False)
    gen = torch.Generator().manual_seed(0)
    batch = sample_candidates(start, problem.goal, [(skill,)], problem.skill_map, problem.encoder, cfg.num_samples, gen,
                              attention="enumerate")
    opt = _Optimiser(problem, batch, cfg, gen, "adam", 0.1, 1e-3, None)
    scores = opt.run()
    ev = evaluate(opt.batch, opt.batch.latents(), problem.skill_map, problem.cost)
    best: dict[int, tuple[float, float, float]] = {}
    for g, grp in enumerate(opt.batch.groups):
        for row in range(grp.size):
            _, attention, _ = opt.batch.candidate(g, row)
            entity, score = attention[0][0], float(scores[g][row])
            if score > best.get(entity, (-1.0,))[0]:
                best[entity] = (score, float(ev.log_feasibility[g][row].exp().prod()), float(ev.cost[g][row]))
    return best


def truth_feasibility(inst: Any, skills: dict[str, Any], encoder: Any, min_points: int,
                      seed: int) -> list[tuple[str, float]]:
    """``(skill, feasibility)`` of every step of the instance's ground-truth chain: the observed pieces the expert
    consumed (in the state before the step) and produced (each output separately), encoded as at planning."""
    from pasta.execute.pipeline import perceive

    obs_index = inst.obs_index
    out = []
    for h, step in enumerate(inst.steps):
        before = (inst.steps[h - 1].state if h else inst.init.x)[obs_index]
        after = step.state[obs_index]
        _, u_in = perceive(before[step.inputs], encoder, min_points=min_points, seed=seed)
        u_out = torch.cat([perceive(after[o], encoder, min_points=min_points, seed=seed)[1][:1] for o in step.outputs])
        with torch.no_grad():
            f = skills[step.skill].log_feasibility(u_in[None], u_out[None]).exp()
        out.append((step.skill, float(f)))
    return out


def main(argv: list[str]) -> int:
    from pasta.config.overrides import script_args
    from pasta.core.planner import PlanningProblem
    from pasta.execute.pipeline import perceive, plan_from_clouds
    from pasta.execute.session import build_session

    given = script_args(argv, __doc__, "python benchmarks/repeated_steps.py")
    args = {"task": "crs_twice", "seeds": "2000-2019", "models": "", "windows": "0", "truth": "0"}
    overrides = []
    for key, value in given.items():
        if key in args:
            args[key] = str(value)
        elif key.startswith("planner"):
            overrides.append(f"{key}={value}")
        else:
            print(f"python benchmarks/repeated_steps.py: unknown key '{key}'; valid: {', '.join(args)}, planner.KEY",
                  file=sys.stderr)
            return 2
    torch.set_num_threads(1)
    session = build_session(args["task"], models=args["models"] or None, config_overrides=overrides)
    skills = {s.name: s for s in session.skills}
    low, high = (np.asarray(b, np.float64) for b in (session.encoder.t_low, session.encoder.t_high))
    repeats = outside = both = 0
    seeds = parse_seeds(args["seeds"])
    for seed in seeds:
        inst = session.task.instance(seed)
        skeleton = tuple(inst.skeleton[: session.horizon]) if session.use_skeleton else None
        plan = plan_from_clouds(inst.init_points, inst.goal, planner=session.planner, skills=session.skills,
                                encoder=session.encoder, cost=session.cost, horizon=session.horizon, seed=seed,
                                skeleton=skeleton)
        pieces, u_goal = perceive(inst.goal, session.encoder, min_points=session.exe.min_points, seed=seed)
        centres = np.array([p.mean(0) for p in pieces], np.float64)
        off = [i for i, c in enumerate(centres) if np.any(c < low - 1e-9) or np.any(c > high + 1e-9)]
        rep = repeated_steps(plan, skills)
        repeats += bool(rep)
        outside += bool(off)
        both += bool(rep) and bool(off)
        line = (f"seed {seed}: {'-'.join(plan.skills)} inputs {[list(s.inputs) for s in plan.steps]} "
                f"repeat at {rep or '-'}; goal centroids (x, y, z) {np.round(centres, 3).tolist()} "
                f"outside the box {off or '-'}")
        if rep and rep[-1] == len(plan.steps) - 1 and args["windows"] not in ("0", "false"):
            start = plan.steps[-2].state
            _, u_obs = perceive(inst.init_points, session.encoder, min_points=session.exe.min_points, seed=seed)
            problem = PlanningProblem(obs=u_obs, goal=u_goal, skills=list(session.skills), encoder=session.encoder,
                                      cost=session.cost, horizon=session.horizon, seed=seed)
            best = last_window_by_attention(problem, session.planner.cfg, torch.as_tensor(start),
                                            plan.steps[-1].skill)
            line += "; last window per entity (score, feasibility, cost): " + ", ".join(
                f"{e}: ({s:.3f}, {f:.2f}, {c:.4f})" for e, (s, f, c) in sorted(best.items()))
        if args["truth"] not in ("0", "false"):
            rated = truth_feasibility(inst, skills, session.encoder, session.exe.min_points, seed)
            line += "; ground-truth steps rated " + ", ".join(f"{name} {f:.3f}" for name, f in rated)
        print(line, flush=True)
    print(f"{len(seeds)} seeds: {repeats} plans repeat a step on the piece it just produced; {outside} goals have "
          f"a piece outside the encoder's centroid box {np.round(low, 3).tolist()} .. {np.round(high, 3).tolist()}; "
          f"{both} both")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
