"""``pasta run task=crs seed=S [planner=NAME] [controller=learned|heuristic] [log=run.mcap]``: one task episode.

Perception (decompose + encode the observation and the goal) -> plan (the configured planner) ->
execution (learned policies or heuristic controllers) -> score (normalised EMD improvement).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from pasta.core.errors import ConfigError, InputError, did_you_mean

HELP = "plan and execute one task instance in the simulator and score it (task=crs seed=S [planner=...] [controller=...])"

EPILOG = """examples:
  pasta run task=crs seed=3                                   # plan with the default planner, learned policies
  pasta run task=crs seed=3 controller=heuristic log=runs/crs3.mcap
  pasta run task=crs seed=3 planner=sampling execute.closed_loop=true
keys of this command: task models controller log horizon execute.<field> (see docs/policies.md);
every other key=value goes to the run config (seed, planner, planner.*)."""

#: success thresholds on the normalised improvement (PASTA paper; strict ">")
THRESHOLDS = {"cut_rearrange": 0.80, "crs": 0.83, "crs_twice": 0.83, "lift_spread": 0.88, "gather_move": 0.65}
_OWN = ("task", "models", "controller", "log", "horizon")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = EPILOG
    parser.add_argument("overrides", nargs="*", metavar="key=value", help="task=NAME is required")


def split_overrides(overrides: list[str]) -> tuple[dict[str, str], dict[str, Any], list[str]]:
    """``(own keys, execute.* fields, the rest for the run config)``; types of execute fields are checked."""
    from pasta.execute import ExecuteConfig

    own: dict[str, str] = {}
    execute: dict[str, Any] = {}
    rest: list[str] = []
    fields = {f.name: f for f in dataclasses.fields(ExecuteConfig)}
    for item in overrides:
        key, eq, value = item.partition("=")
        key, value = key.strip(), value.strip()
        if not eq or not key:
            raise ConfigError(f"argument {item!r} must look like key=value")
        if key in _OWN:
            own[key] = value
        elif key.startswith("execute."):
            name = key[len("execute."):]
            if name not in fields:
                raise ConfigError(f"unknown key '{key}'{did_you_mean(name, fields)}; execute keys: {', '.join(fields)}")
            execute[name] = _convert(key, value, fields[name].type)
        else:
            rest.append(item)
    if "controller" in own:
        execute["controller"] = own.pop("controller")
    return own, execute, rest


def _convert(key: str, raw: str, kind: Any) -> Any:
    kind = kind if isinstance(kind, str) else getattr(kind, "__name__", str(kind))
    try:
        if kind == "bool":
            if raw.lower() not in {"true", "false", "1", "0", "yes", "no"}:
                raise ValueError(raw)
            return raw.lower() in {"true", "1", "yes"}
        if kind == "int":
            return int(raw)
        if kind == "float":
            return float(raw)
    except ValueError:
        raise ConfigError(f"{key}={raw!r}: expected a {kind}") from None
    return raw


def _first(obj: Any, names: tuple[str, ...]) -> Any:
    for n in names:
        value = obj.get(n) if isinstance(obj, dict) else getattr(obj, n, None)
        if value is not None:
            return value
    return None


def task_instance(name: str, seed: int) -> dict[str, Any]:
    """The task's instance for ``seed`` as ``{"particles" | "state", "goal", "sim_config", "horizon", "skeleton", "skills"}``.

    Contract assumed of a registered task (``pasta_register_tasks``): the factory builds an object with
    ``instance(seed)`` (or ``make``/``generate``/``sample``) returning an object or dict with the initial
    ``particles`` (N, 3) or a simulator ``state``, the ``goal`` cloud (G, 3) (a full target particle array
    of the same N is observed through the same particle subset), and optionally ``sim_config``,
    ``horizon``, ``skeleton`` and ``skills``.
    """
    from pasta.plugins import get_plugins

    task = get_plugins().tasks.create(name)
    maker = _first(task, ("instance", "make", "generate", "sample"))
    if maker is None:
        raise InputError(f"task '{name}' has no instance(seed) method")
    inst = maker(seed)
    out = {
        "particles": _first(inst, ("particles", "initial", "init", "dough")),
        "state": _first(inst, ("state", "initial_state")),
        "goal": _first(inst, ("goal", "target", "goal_points")),
        "sim_config": _first(inst, ("sim_config", "sim_cfg")) or _first(task, ("sim_config", "sim_cfg")),
        "horizon": _first(inst, ("horizon",)) or _first(task, ("horizon",)),
        "skeleton": _first(inst, ("skeleton",)) or _first(task, ("skeleton",)),
        "skills": _first(inst, ("skills",)) or _first(task, ("skills",)),
    }
    if out["goal"] is None or (out["particles"] is None and out["state"] is None):
        raise InputError(f"task '{name}' instance lacks the initial particles/state or the goal cloud")
    return out


def run(args: argparse.Namespace) -> int:
    from pasta.config import load_config, section, to_yaml
    from pasta.execute import ExecuteConfig
    from pasta.execute.pipeline import run_episode
    from pasta.plugins import get_plugins

    own, execute_kw, rest = split_overrides(list(args.overrides))
    if not own.get("task"):
        raise ConfigError("`pasta run` needs task=NAME (e.g. task=crs)")
    models = Path(own.get("models", "models"))
    groups = {"encoder": "pc_vae", "cost_model": "set_cost"}  # the same defaults as `pasta plan`
    keys = {r.partition("=")[0].strip() for r in rest}
    for group, default in groups.items():
        if group not in keys:
            rest.insert(0, f"{group}={default}")
    if "models" in own:  # trained weights under the given root unless set explicitly
        for key, sub in (("encoder.weights", "vae"), ("cost_model.weights", "cost")):
            if key not in keys:
                rest.append(f"{key}={models / sub}")
    plugins = get_plugins()
    cfg = load_config(rest, plugins=plugins)
    exe = ExecuteConfig(**execute_kw)
    name, seed = own["task"], int(cfg.seed)
    inst = task_instance(name, seed)
    skill_names = list(inst["skills"] or plugins.skills.names())
    skills = [plugins.skills.create(n) for n in skill_names]
    choice = {g: v for g, v in (r.partition("=")[::2] for r in rest) if g in groups}

    def conf(key: str) -> Any:
        return section(cfg, key) if cfg[key] is not None else None

    encoder = plugins.encoders.create(choice["encoder"], conf("encoder"))
    cost = plugins.cost_models.create(choice["cost_model"], conf("cost_model"))
    from pasta.nn.loading import attach_feasibility

    attach_feasibility([s for s in skills if s.feasibility_model is None], models, latent_dim=encoder.latent_dim)
    if exe.controller == "learned":
        from pasta.policy import POLICY_DIR
        from pasta.policy.learned import load_policy

        for s in skills:
            load_policy(models / POLICY_DIR / s.name, s, device=str(cfg.device))
    planner = plugins.planners.create(cfg.planner.name, section(cfg, "planner"))

    from pasta.sim import SimConfig, Simulator

    sim_cfg = inst["sim_config"] or SimConfig()
    if isinstance(sim_cfg, dict):
        sim_cfg = SimConfig(**sim_cfg)
    sim = Simulator(sim_cfg, seed=seed)
    if inst["state"] is not None:
        sim.set_state(inst["state"])
        obs = sim.observe()
    else:
        obs = sim.reset(np.asarray(inst["particles"], np.float32), seed=seed)
    goal = np.asarray(inst["goal"], np.float32)
    if inst["state"] is None and goal.shape == np.shape(inst["particles"]) and len(goal) != len(obs.dough):
        goal = goal[obs.dough_index]  # the same particles as the observation
    horizon = int(own.get("horizon") or inst["horizon"] or 3)

    logger = None
    if own.get("log"):
        from pasta.io import RunLogger

        meta = {"task": name, "seed": seed, "planner": cfg.planner.name, "controller": exe.controller,
                "models": str(models), "pasta": __import__("pasta").__version__}
        logger = RunLogger(own["log"], config_yaml=to_yaml(cfg) + "execute: " + json.dumps(dataclasses.asdict(exe)) + "\n",
                           metadata=meta)
    try:
        episode = run_episode(sim, goal, planner=planner, skills=skills, encoder=encoder, cost=cost, horizon=horizon,
                              seed=seed, skeleton=inst["skeleton"], cfg=exe, logger=logger)
    finally:
        if logger is not None:
            logger.close()
    print(episode.plan.summary())
    res = episode.result
    for s in res.steps:
        print(f"  executed {s.step + 1}. {s.skill:<6} on observed pieces {list(s.attended)}: {s.env_steps} steps"
              f"{' (done)' if s.done else ''}, improvement {s.normalized_improvement:.3f}")
    if res.diverged:
        print(f"simulation diverged: {res.diverged}", file=sys.stderr)
    threshold = THRESHOLDS.get(name)
    verdict = "" if threshold is None else f" ({'success' if res.normalized_improvement > threshold else 'failure'}, threshold {threshold})"
    print(f"task {name} seed {seed}: normalised improvement {res.normalized_improvement:.3f}{verdict}")
    if own.get("log"):
        print(f"run logged to {own['log']} (open in Foxglove, or `pasta replay {own['log']}`)")
    return 0
