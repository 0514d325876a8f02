"""Choose the learned controller's stopping rule (done threshold, ``min_steps``, ``max_steps``) on validation configs.

The learned controller stops at its first step ``i`` (``i + 1 >= min_steps`` actions) whose done
probability exceeds ``done_threshold``, or after ``max_steps`` actions
(:class:`pasta.policy.learned.PolicyController`). Up to that step
the rollout does not depend on the rule (the controller's point subsampling is seeded, the simulator is
deterministic), so one rollout that never stops, with the simulator state and the done probability
recorded at every step, scores every rule: restore the state where the rule stops, let the dough settle
(the idle steps of :func:`pasta.tasks.executor.run_skill`) and measure the normalised improvement.

Use validation configs (a config stream the test table does not use, e.g. ``seed=2000``), then report
the chosen rule on the test configs (``seed=1000``) with :mod:`pasta.policy.evaluate`::

    python -m pasta.policy.select models=models skill=roll n=20 seed=2000 \\
           [thresholds=0.3,0.4,0.5,0.6,0.7] [min_steps=1] [max_steps=0,60,80] [out=FILE.json] [write=1]

(``max_steps`` 0: no cap of the policy's own, only the skill's step limit; ``write=1`` stores the selected
rule in the checkpoint's ``model.json`` under ``config.controller``, which
:meth:`~pasta.policy.learned.LearnedPolicy.load` uses as its defaults.)
"""

from __future__ import annotations

import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from pasta.core import Controller, SkillObservation
from pasta.core.metrics import emd, normalized_improvement

__all__ = ["RecordingController", "select_rule", "stop_index", "sweep", "write_rule"]


def stop_index(probs: Sequence[float], actions: Sequence[np.ndarray], threshold: float, min_steps: int,
               max_steps: int = 0) -> int:
    """Env steps taken when the rule ``(threshold, min_steps)`` stops a rollout whose controller output
    done probability ``probs[i]`` and action ``actions[i]`` at its step ``i``: like
    :func:`~pasta.tasks.executor.run_skill`, a done with a non-zero action is applied then ends the
    step, an all-zero one ends it without stepping; ``len(probs)`` when the rule never fires.
    ``max_steps`` > 0: the controller also reports done at its ``max_steps``-th action."""
    for i, (p, a) in enumerate(zip(probs, actions)):
        if i + 1 >= min_steps and p > threshold or 0 < max_steps <= i + 1:
            return i + 1 if np.any(np.clip(np.asarray(a, np.float32), -1.0, 1.0)) else i
    return len(probs)


class RecordingController(Controller):
    """Wraps a learned :class:`~pasta.policy.learned.PolicyController`: never reports done, records at
    each step the simulator state (before the step), the done probability and the action."""

    def __init__(self, inner: Any, sim: Any) -> None:
        self.inner, self.sim = inner, sim
        self.states: list[Any] = []
        self.probs: list[float] = []
        self.actions: list[np.ndarray] = []

    def reset(self, obs: SkillObservation) -> None:
        self.inner.reset(obs)
        self.states, self.probs, self.actions = [], [], []

    def approach_pose(self, *args: Any, **kwargs: Any) -> Any:
        """The wrapped controller's own start pose (a learned reset pose), if it has one."""
        own = getattr(self.inner, "approach_pose", None)
        return own(*args, **kwargs) if callable(own) else None

    def act(self, obs: SkillObservation) -> tuple[np.ndarray, bool]:
        self.states.append(self.sim.get_state())
        action, _ = self.inner.act(obs)
        self.probs.append(float(self.inner.last_done_prob))
        self.actions.append(np.asarray(action, np.float32))
        return action, False


def sweep(sim: Any, skill: Any, configs: Sequence[Any], thresholds: Sequence[float], min_steps: Sequence[int],
          caps: Sequence[int] = (0,), *, max_steps: int | None = None, idle_steps: int = 10, emd_points: int = 500,
          verbose: bool = True) -> dict[str, Any]:
    """Score every rule ``(threshold, min_steps, cap)`` on every config with one rollout per config
    (``cap``: the controller's own ``max_steps``, 0 = none; ``max_steps``: the rollout's step limit,
    default the skill's).

    ``skill`` must carry its learned policy (``skill.policy()``). Returns ``{"rules": [[t, m, cap], ...],
    "ni": [[per-config NI for each rule], ...] (configs x rules), "steps": same shape}``."""
    from pasta.tasks.executor import run_skill

    rules = [(float(t), int(m), int(c)) for c in caps for m in min_steps for t in thresholds]
    ni_rows, step_rows = [], []
    for cfg in configs:
        sim.set_state(cfg.state)
        piece = sim.observe().dough
        approach = skill.expert_approach_pose(piece, cfg.params, scene=piece) if hasattr(skill, "expert_approach_pose") else None
        run_skill(sim, skill, skill.expert(cfg.params), np.arange(len(piece)), None, approach=approach)
        goal = sim.observe().dough
        emd0 = emd(piece, goal, n=emd_points, seed=cfg.seed)
        sim.set_state(cfg.state)
        rec = RecordingController(skill.policy(), sim)
        run_skill(sim, skill, rec, np.arange(len(piece)), goal, max_steps=max_steps, idle_steps=0, park=False)
        final = sim.get_state()
        row_ni, row_steps, cache = [], [], {}
        for t, m, c in rules:
            k = stop_index(rec.probs, rec.actions, t, m, c)
            if k not in cache:
                sim.set_state(rec.states[k] if k < len(rec.states) else final)
                for _ in range(max(0, idle_steps)):
                    sim.step()
                cache[k] = normalized_improvement(emd0, emd(sim.observe().dough, goal, n=emd_points, seed=cfg.seed))
            row_ni.append(cache[k])
            row_steps.append(k)
        ni_rows.append(row_ni)
        step_rows.append(row_steps)
        if verbose:
            best = int(np.argmax(row_ni))
            print(f"  {skill.name} seed {cfg.seed}: {len(rec.probs)} steps recorded, NI {min(row_ni):.3f}..{max(row_ni):.3f}"
                  f" (best rule {rules[best]})", file=sys.stderr, flush=True)
    return {"rules": [list(r) for r in rules], "ni": ni_rows, "steps": step_rows}


def select_rule(result: dict[str, Any]) -> tuple[tuple[float, ...], float]:
    """The rule with the highest mean normalised improvement (ties: the first in ``result["rules"]``)
    and that mean."""
    means = np.asarray(result["ni"], np.float64).mean(0)
    best = int(np.argmax(means))
    return tuple(result["rules"][best]), float(means[best])


def write_rule(directory: str | Path, rule: dict[str, Any]) -> None:
    """Store ``rule`` (``done_threshold``, ``min_steps``, ``max_steps``) as the controller defaults of the
    policy checkpoint in ``directory`` (``model.json``: ``config.controller``)."""
    path = Path(directory) / "model.json"
    doc = json.loads(path.read_text())
    doc["config"]["controller"] = rule
    path.write_text(json.dumps(doc, indent=2) + "\n")


def main(argv: Sequence[str] | None = None) -> int:
    import torch

    args = dict(a.split("=", 1) for a in (sys.argv[1:] if argv is None else argv))
    models = Path(args.get("models", "models"))
    name = args.get("skill", "roll")
    n, seed = int(args.get("n", 20)), int(args.get("seed", 2000))
    thresholds = [float(v) for v in args.get("thresholds", "0.3,0.4,0.5,0.6,0.7").split(",") if v]
    min_steps = [int(v) for v in args.get("min_steps", "1").split(",") if v]
    caps = [int(v) for v in args.get("max_steps", "0").split(",") if v]
    torch.set_num_threads(int(args.get("threads", 1)))
    from pasta.plugins import get_plugins
    from pasta.policy import POLICY_DIR
    from pasta.policy.evaluate import make_configs
    from pasta.policy.learned import load_policy
    from pasta.sim import SimConfig, Simulator

    sim_kw = json.loads(args["sim"]) if "sim" in args else {}
    sim = Simulator(SimConfig(**{"n_particles": 5000, "obs_points": 1000, "max_particles": 10000, **sim_kw}))
    skill = get_plugins().skills.create(name)
    kw: dict[str, Any] = {"start_step": int(args["start_step"])} if "start_step" in args else {}
    if args.get("reset") in ("0", "false", "off"):
        kw["reset"] = False  # ignore a learned reset pose beside the policy
    load_policy(models / POLICY_DIR / name, skill, **kw)
    max_steps = int(args["learned_max_steps"]) if "learned_max_steps" in args else None
    # the skill's own limit, unless a cap is larger (then the cap is the limit)
    limit = max([max_steps or int(getattr(skill, "max_steps", 50)), *caps])
    result = sweep(sim, skill, make_configs(skill, sim, n, seed), thresholds, min_steps, caps, max_steps=limit)
    means = np.asarray(result["ni"]).mean(0)
    print(f"| {name}: max_steps, min_steps \\ done_threshold | " + " | ".join(f"{t:g}" for t in thresholds) + " |")
    print("|---" * (len(thresholds) + 1) + "|")
    for j in range(len(means) // len(thresholds)):
        _, m, c = result["rules"][j * len(thresholds)]
        print(f"| {c or '-'}, {m} | " + " | ".join(f"{means[j * len(thresholds) + i]:.3f}" for i in range(len(thresholds))) + " |")
    (t, m, c), best = select_rule(result)
    rule = {"done_threshold": t, "min_steps": m, "max_steps": c}
    print(f"selected on seed={seed}: done_threshold={t:g} min_steps={m} max_steps={c} (mean NI {best:.3f})")
    if "out" in args:
        Path(args["out"]).write_text(json.dumps({"skill": name, "seed": seed, "n": n, "models": str(models),
                                                 "selected": {**rule, "mean_ni": best}, **result}, indent=1) + "\n")
    if args.get("write", "0") not in ("0", "false", ""):
        write_rule(models / POLICY_DIR / name, rule)
        print(f"wrote the rule to {models / POLICY_DIR / name / 'model.json'} (config.controller)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
