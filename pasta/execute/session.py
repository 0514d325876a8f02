"""Everything one evaluation method needs to run task episodes: models, planner, controllers.

``pasta run`` (one episode) and ``pasta eval`` (a fixed test set) both build a :class:`Session` with
:func:`build_session` and call :meth:`Session.episode` per seed. Methods (``METHODS``):

- ``pasta``: entity latents, the configured planner (default exhaustive; receding horizon for
  ``crs_twice``, as in the paper), the shipped or given weights.
- ``sampling``: the same with the sampling (CEM) planner.
- ``flat``: the Flat 3D baseline: the whole scene as one latent (``models/flat``), skills 1 -> 1.
- ``oracle``: no planning: the task's ground-truth skill chain with the heuristic controllers.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pasta.core.errors import ConfigError, did_you_mean

__all__ = ["METHODS", "EpisodeOutcome", "Session", "build_session"]

METHODS = ("pasta", "sampling", "flat", "oracle")


@dataclass
class EpisodeOutcome:
    """One scored episode: improvement, success, the plan (``None`` for the oracle) and wall times."""

    task: str
    method: str
    seed: int
    improvement: float
    success: bool
    plan: Any = None
    result: Any = None
    plan_s: float = 0.0
    execute_s: float = 0.0
    final_dough: Any = None
    info: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        out = {"task": self.task, "method": self.method, "seed": self.seed, "improvement": self.improvement,
               "success": self.success, "plan_s": round(self.plan_s, 3), "execute_s": round(self.execute_s, 3)}
        if self.plan is not None:
            out["skeleton"] = list(self.plan.skills)
            out["plan_score"] = self.plan.score
        if self.result is not None:
            out["steps"] = [s.to_dict() for s in self.result.steps]
            out["diverged"] = self.result.diverged
            if self.result.replan_errors:
                out["replan_errors"] = list(self.result.replan_errors)
        return {**out, **self.info}


@dataclass
class Session:
    """A task with a method's models, planner and execution settings (see :func:`build_session`)."""

    task: Any
    method: str
    cfg: Any  # the resolved RunConfig
    exe: Any  # ExecuteConfig
    models: Path
    horizon: int
    use_skeleton: bool
    planner: Any = None
    skills: list[Any] = field(default_factory=list)
    encoder: Any = None
    cost: Any = None
    #: how the skill set was chosen (``skills=`` or the trained ones; :mod:`pasta.execute.skillset`)
    skill_choice: Any = None

    def describe(self) -> dict[str, Any]:
        from omegaconf import OmegaConf

        planner = OmegaConf.to_container(self.cfg.planner) if self.method != "oracle" else None
        return {"task": self.task.name, "method": self.method, "planner": getattr(self.cfg.planner, "name", None),
                "planner_settings": planner,
                "controller": "heuristic" if self.method == "oracle" else self.exe.controller,
                "execute_settings": dataclasses.asdict(self.exe),
                "horizon": self.horizon, "models": str(self.models), "skeleton_given": self.use_skeleton,
                "skills": [sk.name for sk in self.skills] if self.method != "oracle" else list(self.task.skeleton),
                "task_config": dataclasses.asdict(self.task.config),
                "feasibility_training": self.feasibility_training()}

    def feasibility_training(self) -> dict[str, dict[str, Any]]:
        """Per planned skill, the negatives its attached feasibility network was trained with
        (``hard_per_positive``, ``shift_per_positive`` of its checkpoint; skills without one are left out), so a
        summary tells an ablation's networks (e.g. no hard negatives) from the shipped ones."""
        out: dict[str, dict[str, Any]] = {}
        if self.method == "oracle":
            return out
        for sk in self.skills:
            train = getattr(getattr(sk, "feasibility_model", None), "train_settings", None)
            if train is not None:
                out[sk.name] = {k: train[k] for k in ("hard_per_positive", "shift_per_positive") if k in train}
        return out

    def episode(self, seed: int, *, logger: Any = None, sim: Any = None) -> EpisodeOutcome:
        """Plan and execute the task instance ``seed`` (generated and cached on first use) and score it."""
        from pasta.execute.pipeline import run_episode

        inst = self.task.instance(seed)
        sim = sim if sim is not None else self.task.make_sim()
        if self.method == "oracle":
            from pasta.tasks.oracle import run_oracle

            res = run_oracle(self.task, inst, sim=sim)
            return EpisodeOutcome(self.task.name, self.method, seed, float(res.score.improvement), bool(res.score.success),
                                  execute_s=res.wall_s, final_dough=sim.observe().dough)
        sim.set_state(inst.init)
        skeleton = tuple(inst.skeleton[: self.horizon]) if self.use_skeleton else None
        episode = run_episode(sim, inst.goal, planner=self.planner, skills=self.skills, encoder=self.encoder,
                              cost=self.cost, horizon=self.horizon, seed=seed, skeleton=skeleton, cfg=self.exe,
                              logger=logger)
        score = self.task.score(episode.result.final_dough, inst)
        plan_s = float(episode.plan.timings.get("total", 0.0))
        exec_s = float(sum(s.wall_s for s in episode.result.steps))
        return EpisodeOutcome(self.task.name, self.method, seed, float(score.improvement), bool(score.success),
                              plan=episode.plan, result=episode.result, plan_s=plan_s, execute_s=exec_s,
                              final_dough=episode.result.final_dough)


def build_session(task_name: str, *, method: str = "pasta", models: str | Path | None = None,
                  config_overrides: list[str] | None = None, execute: dict[str, Any] | None = None,
                  horizon: int | None = None, skeleton: str = "auto", plugins: Any = None,
                  skills: str | list[str] | None = None, task_settings: dict[str, Any] | None = None) -> Session:
    """Load a method's models and planner for ``task_name``.

    Args:
        method: one of :data:`METHODS`.
        models: weights root (``pasta train ... out=DIR``); ``None``: the shipped weights.
        config_overrides: ``key=value`` items of the run config (``seed``, ``planner``, ``planner.*``, ...).
        execute: :class:`~pasta.execute.ExecuteConfig` fields (strings are parsed).
        horizon: planning horizon (default: the task's).
        skeleton: ``auto`` (given for ``crs_twice`` only, as in the paper), ``true`` or ``false``.
        skills: the skills to plan with (``"cut,push,roll"``); ``None``: every registered skill that has
            trained weights (:func:`pasta.execute.skillset.choose_skills`; the others are left out and
            ``session.skill_choice.warning()`` names them).
        task_settings: task config fields to set (``{"distractors": "4"}``; ``task.<setting>=`` on the
            command line, :func:`pasta.tasks.split_task_settings`); other instances, other cache entries.

    Raises:
        ConfigError: the task's ground-truth chain needs a skill that is not chosen.
    """
    from pasta.config import load_config, section
    from pasta.config.overrides import build
    from pasta.execute import ExecuteConfig
    from pasta.plugins import get_plugins
    from pasta.tasks import get_task
    from pasta.weights import models_root, weight_overrides

    if method not in METHODS:
        raise ConfigError(f"unknown method '{method}'{did_you_mean(method, METHODS)}; known methods: {', '.join(METHODS)}")
    task = get_task(task_name, **dict(task_settings or {}))  # unknown task (or setting) -> error listing the known ones
    plugins = plugins or get_plugins()
    root = models_root(models)
    rest = list(config_overrides or [])
    keys = {r.partition("=")[0].strip() for r in rest}
    if method == "sampling" and "planner" not in keys:
        rest.append("planner=sampling")
    if method in ("pasta", "flat") and "planner" not in keys and task_name == "crs_twice":
        rest.append("planner=receding_horizon")
    if method != "flat":  # the flat models load from ROOT/flat (pasta.nn.flat.load_flat)
        rest += weight_overrides(root, rest)
    cfg = load_config(rest, plugins=plugins)
    exe = build(ExecuteConfig, dict(execute or {}), command="pasta run/eval")
    exe = dataclasses.replace(exe, emd_points=task.config.emd_points, emd_seed=task.config.emd_seed)
    given = str(skeleton).lower()
    if given not in ("auto", "true", "false", "1", "0", "yes", "no"):
        raise ConfigError(f"skeleton must be auto, true or false, got {skeleton!r}")
    use_skeleton = given in ("true", "1", "yes") or (given == "auto" and task_name == "crs_twice")
    session = Session(task, method, cfg, exe, root, int(horizon or task.horizon), use_skeleton)
    if method == "oracle":
        return session
    from pasta.execute.skillset import choose_skills, needs_feasibility_network

    choice = choose_skills(skills, root, plugins=plugins, policy=exe.controller == "learned", flat=method == "flat")
    choice.require(task.skeleton, f"task '{task.name}' (its ground-truth chain)")
    chosen = [task.skill(n) for n in choice.names]
    if exe.controller == "learned":
        from pasta.policy import POLICY_DIR
        from pasta.policy.learned import load_policy

        for s in chosen:
            load_policy(root / POLICY_DIR / s.name, s, device=str(cfg.device))
    if method == "flat":
        from pasta.nn.flat import load_flat

        encoder, cost, chosen = load_flat(root / "flat", chosen, device=str(cfg.device))
    else:
        from pasta.nn.loading import attach_feasibility

        encoder = plugins.encoders.create(cfg.encoder.name, section(cfg, "encoder"))
        cost = plugins.cost_models.create(cfg.cost_model.name, section(cfg, "cost_model"))
        attach_feasibility([s for s in chosen if needs_feasibility_network(s)], root, latent_dim=encoder.latent_dim)
    session.skill_choice = choice
    session.skills, session.encoder, session.cost = chosen, encoder, cost
    session.planner = plugins.planners.create(cfg.planner.name, section(cfg, "planner"))
    return session

