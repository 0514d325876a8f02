"""Single-skill evaluation: learned policy vs heuristic controller vs scripted expert.

A *config* is an initial scene (the skill's demonstration scene, :meth:`pasta.core.Skill.demo_scene`)
and expert parameters, drawn from a seed that the training demonstrations did not use. Its goal is what the scripted expert makes of the scene (the simulator is
deterministic): the observed dough after the expert's run. Each controller then starts from the same
initial state with that goal cloud as its sub-goal, and is scored by the normalised improvement
``(EMD_0 - EMD_T) / EMD_0`` of the observed dough to the goal. The expert's own score is its
reproducibility (1 for a deterministic simulator).

``python -m pasta.train.evaluate models=models n=20 seed=1000 [skills=a,b] [scene=VARIANT] [done_threshold=T] [min_steps=M] [max_steps=C] [reset=0] [start_step=S] [out=FILE.json]``
(the stopping rule: the checkpoint's own, ``config.controller``, unless given; a learned reset pose
beside the policy, ``reset.*``, is used unless ``reset=0``, its step counter starting at ``start_step``.)
(the simulator as ``pasta demos`` configures it: 5,000 particles, 1,000 observed.)
(``skills``: default every registered skill that can make demonstrations; ``scene``: a demonstration scene
variant every listed skill has, e.g. ``skills=push scene=wide``, ``skills=roll scene=board``.)
prints the table of docs/policies.md.
"""

from __future__ import annotations

import json
import sys
import time
import zlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pasta.core.metrics import emd, normalized_improvement

__all__ = ["SkillConfig", "evaluate_skill", "main", "make_configs"]

CONTROLLERS = ("learned", "heuristic", "expert")


@dataclass
class SkillConfig:
    """One held-out single-skill config: the initial simulator state, the expert's params, its index."""

    skill: str
    seed: int
    state: Any
    params: dict[str, float]


def _scene(skill: Any, rng: np.random.Generator, n: int, floor_y: float, scene: str = "default") -> np.ndarray:
    """``(n, 3)`` particles of the skill's demonstration scene ``scene`` (as ``pasta demos`` draws it)."""
    from pasta.demos.scene import scene_boxes, scene_particles

    return scene_particles(scene_boxes(skill, rng, floor_y, scene), n, rng)[0]


def make_configs(skill: Any, sim: Any, n: int, seed: int, settle_steps: int = 10,
                 scene: str = "default") -> list[SkillConfig]:
    """``n`` configs of ``skill``: scene and expert parameters from the stream ``(seed, crc32(skill), i)``
    (``pasta demos`` uses its own base seed, 0 by default, so a different ``seed`` gives held-out
    configs), after ``settle_steps`` zero-action steps as in the demonstrations. ``scene``: a scene
    variant of the skill (:attr:`pasta.core.Skill.demo_variants`, e.g. push's ``wide``), with its tools
    placed as ``pasta demos`` places them; ``skill`` should carry that variant's config
    (:func:`pasta.demos.generate.skill_config`) so that the expert's parameters are drawn as there."""
    from pasta.demos.generate import demo_tools

    out = []
    for i in range(n):
        rng = np.random.default_rng([seed, zlib.crc32(skill.name.encode()), i])
        sim.reset(_scene(skill, rng, sim.cfg.n_particles, sim.floor_y, scene), seed=int(rng.integers(2**31)))
        for name, pose in demo_tools(skill, scene).items():
            sim.set_tool_pose(name, pose.position, yaw=pose.yaw)
        for _ in range(settle_steps):
            sim.step()
        params = {k: float(v) for k, v in skill.sample_expert_params(sim.observe().dough, rng).items()}
        out.append(SkillConfig(skill.name, i, sim.get_state(), params))
    return out


def _run(sim: Any, skill: Any, controller: Any, goal: np.ndarray | None, approach: Any = None,
         max_steps: int | None = None) -> tuple[int, bool]:
    from pasta.tasks.executor import run_skill

    obs = sim.observe()
    res = run_skill(sim, skill, controller, np.arange(len(obs.dough)), goal, approach=approach, max_steps=max_steps)
    return res.steps, res.done


def evaluate_skill(sim: Any, skill: Any, configs: Sequence[SkillConfig], controllers: Sequence[str] = CONTROLLERS,
                   *, emd_points: int = 500, learned_max_steps: int | None = None,
                   verbose: bool = True) -> dict[str, list[dict[str, Any]]]:
    """Score every controller on every config; returns ``{controller: [per-config records]}``.

    ``learned_max_steps``: step limit of the learned policy (default: the skill's own, like the others).
    """
    records: dict[str, list[dict[str, Any]]] = {c: [] for c in controllers}
    for cfg in configs:
        sim.set_state(cfg.state)
        start = cfg.state
        piece = sim.observe().dough
        approach = skill.expert_approach_pose(piece, cfg.params, scene=piece)
        _run(sim, skill, skill.expert(cfg.params), None, approach)
        goal = sim.observe().dough
        emd0 = emd(piece, goal, n=emd_points, seed=cfg.seed)
        for name in controllers:
            sim.set_state(start)
            t0 = time.perf_counter()
            try:
                if name == "expert":
                    steps, done = _run(sim, skill, skill.expert(cfg.params), None, approach)
                else:
                    ctl = skill.policy() if name == "learned" else skill.controller()
                    steps, done = _run(sim, skill, ctl, goal, max_steps=learned_max_steps if name == "learned" else None)
                final = sim.observe().dough
                ni = normalized_improvement(emd0, emd(final, goal, n=emd_points, seed=cfg.seed))
                err = None
            except Exception as exc:  # noqa: BLE001 - a diverged or failing run scores 0 and is reported
                steps, done, ni, err = 0, False, 0.0, f"{type(exc).__name__}: {exc}"
            rec = {"seed": cfg.seed, "ni": ni, "steps": steps, "done": done, "emd0": emd0,
                   "wall_s": time.perf_counter() - t0, "error": err}
            records[name].append(rec)
            if verbose:
                print(f"  {skill.name} seed {cfg.seed} {name:<9} NI {ni:6.3f}  steps {steps:3d}{' done' if done else ''}"
                      f"{'  ' + err if err else ''}", file=sys.stderr, flush=True)
    return records


def table(results: dict[str, dict[str, list[dict[str, Any]]]]) -> str:
    """Markdown table: mean (std) normalised improvement per skill and controller, learned / expert ratio."""
    lines = ["| skill | configs | learned policy | heuristic controller | scripted expert | learned / expert |",
             "|---|---|---|---|---|---|"]
    for skill, recs in results.items():
        cells, means = [], {}
        for c in CONTROLLERS:
            if c in recs and recs[c]:
                v = np.array([r["ni"] for r in recs[c]])
                means[c] = float(v.mean())
                cells.append(f"{v.mean():.3f} ({v.std():.3f})")
            else:
                cells.append("-")
        ratio = f"{means['learned'] / means['expert']:.2f}" if "learned" in means and means.get("expert") else "-"
        n = max(len(r) for r in recs.values())
        lines.append(f"| {skill} | {n} | " + " | ".join(cells) + f" | {ratio} |")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    import torch

    from pasta.config.overrides import script_args

    args = script_args(argv, __doc__, "python -m pasta.train.evaluate")
    models = Path(args.get("models", "models"))
    n, seed = int(args.get("n", 20)), int(args.get("seed", 1000))
    if "skills" in args:
        names = [s for s in args["skills"].split(",") if s]
    else:
        from pasta.demos import demo_skills

        names = demo_skills()
    controllers = [c for c in args.get("controllers", ",".join(CONTROLLERS)).split(",") if c]
    torch.set_num_threads(int(args.get("threads", 1)))
    from pasta.plugins import get_plugins
    from pasta.policy import POLICY_DIR
    from pasta.policy.learned import load_policy
    from pasta.sim import SimConfig, Simulator

    sim_kw = json.loads(args["sim"]) if "sim" in args else {}
    sim = Simulator(SimConfig(**{"n_particles": 5000, "obs_points": 1000, "max_particles": 10000, **sim_kw}))
    from pasta.demos.generate import skill_config

    scene = args.get("scene", "default")
    results = {}
    for name in names:
        skill = get_plugins().skills.create(name, skill_config(name, scene))
        if "learned" in controllers:
            kw = {"done_threshold": float(args["done_threshold"])} if "done_threshold" in args else {}
            for key in ("min_steps", "max_steps", "start_step"):
                if key in args:
                    kw[key] = int(args[key])
            if args.get("reset") in ("0", "false", "off"):
                kw["reset"] = False  # ignore a learned reset pose beside the policy
            load_policy(models / POLICY_DIR / name, skill, **kw)
        max_steps = int(args["learned_max_steps"]) if "learned_max_steps" in args else None
        results[name] = evaluate_skill(sim, skill, make_configs(skill, sim, n, seed, scene=scene), controllers,
                                       learned_max_steps=max_steps)
    print(table(results))
    if "out" in args:
        Path(args["out"]).write_text(json.dumps(results, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
