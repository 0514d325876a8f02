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

from pasta.core.errors import ConfigError, did_you_mean

HELP = "plan and execute one task instance in the simulator and score it (task=crs seed=S [planner=...] [controller=...])"

EPILOG = """examples:
  pasta run task=crs seed=3                                   # plan with the default planner, learned policies
  pasta run task=crs seed=3 controller=heuristic log=runs/crs3.mcap
  pasta run task=crs seed=3 planner=sampling execute.closed_loop=true
keys of this command: task models controller log horizon skeleton=auto|true|false execute.<field>
(see docs/policies.md; the skeleton is given for crs_twice only, as in the paper);
every other key=value goes to the run config (seed, planner, planner.*)."""

_OWN = ("task", "models", "controller", "log", "horizon", "skeleton")


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
    from pasta.tasks import get_task

    task = get_task(name)
    exe = dataclasses.replace(exe, emd_points=task.config.emd_points, emd_seed=task.config.emd_seed)
    skills = [task.skill(n) for n in plugins.skills.names()]
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

    inst = task.instance(seed)  # generated by the task's expert chain (cached)
    sim = task.make_sim()
    sim.set_state(inst.init)
    goal = inst.goal  # the observed goal cloud: the same particles as the observation
    horizon = int(own.get("horizon") or task.horizon)
    given = own.get("skeleton", "auto").lower()
    use_skeleton = given in ("true", "1", "yes") or (given == "auto" and name == "crs_twice")  # as in the paper
    skeleton = tuple(inst.skeleton) if use_skeleton else None

    logger = None
    if own.get("log"):
        from pasta.io import RunLogger

        meta = {"task": name, "seed": seed, "planner": cfg.planner.name, "controller": exe.controller,
                "models": str(models), "pasta": __import__("pasta").__version__}
        logger = RunLogger(own["log"], config_yaml=to_yaml(cfg) + "execute: " + json.dumps(dataclasses.asdict(exe)) + "\n",
                           metadata=meta)
    try:
        episode = run_episode(sim, goal, planner=planner, skills=skills, encoder=encoder, cost=cost, horizon=horizon,
                              seed=seed, skeleton=skeleton, cfg=exe, logger=logger)
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
    score = task.score(res.final_dough, inst)
    verdict = "success" if score.success else "failure"
    print(f"task {name} seed {seed}: normalised improvement {score.improvement:.3f} ({verdict}, threshold {task.threshold})")
    if own.get("log"):
        print(f"run logged to {own['log']} (open in Foxglove, or `pasta replay {own['log']}`)")
    return 0
