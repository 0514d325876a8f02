"""Everything one evaluation method needs to run task episodes: models, planner, controllers, settings.

``pasta run`` (one episode) and ``pasta eval`` (a fixed test set) both build a :class:`Session` with
:func:`build_session` from one resolved run config (:mod:`pasta.config`) and call :meth:`Session.episode`
per seed. Methods (``method=``, :data:`pasta.config.run.METHODS`):

- ``pasta``: entity latents, the configured planner (a task may ask for its own, :attr:`pasta.core.Task.run_defaults`:
  crs_twice plans with the receding-horizon planner and its skeleton given, as in the paper), the shipped
  or given weights;
- ``flat``: the Flat 3D baseline: the whole scene as one latent (``MODELS/flat``), skills 1 -> 1;
- ``oracle``: no planning: the task's ground-truth skill chain with the heuristic controllers;
- ``trajopt``: no planning: Adam on the ground-truth tool chain's actions through the differentiable simulator
  (:mod:`pasta.execute.trajopt`, ``trajopt.*``).

Python use::

    from pasta.execute.session import build_session
    session = build_session("crs", execute={"controller": "learned"})
    outcome = session.episode(1000)          # plan, execute, score
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pasta.core.errors import ConfigError

__all__ = ["NO_PLANNER", "EpisodeOutcome", "Session", "as_overrides", "build_session"]

#: methods that run the task's ground-truth chain: no planner, skill set or weights
NO_PLANNER = ("oracle", "trajopt")


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
            flags = self.plan.info.get("flags")
            if flags:
                out["flags"] = flags
        if self.result is not None:
            out["steps"] = [s.to_dict() for s in self.result.steps]
            out["diverged"] = self.result.diverged
            if self.result.decisions:
                out["loop"] = self.result.decisions
            if self.result.disturbance:
                out["disturbance"] = self.result.disturbance
        return {**out, **self.info}


@dataclass
class Session:
    """A task with a method's models, planner and settings (see :func:`build_session`)."""

    task: Any
    cfg: Any  # the resolved RunConfig (omegaconf)
    models: Path
    horizon: int
    planner: Any = None
    skills: list[Any] = field(default_factory=list)
    encoder: Any = None
    cost: Any = None
    #: how the skill set was chosen (``skills=`` or the trained ones; :mod:`pasta.execute.skillset`)
    skill_choice: Any = None

    @property
    def method(self) -> str:
        return str(self.cfg.method)

    @property
    def exe(self) -> Any:
        """The ``execute`` section (:class:`pasta.config.ExecuteConfig`)."""
        from pasta.config import section

        return section(self.cfg, "execute")

    @property
    def perception(self) -> Any:
        from pasta.config import section

        return section(self.cfg, "perception")

    @property
    def check(self) -> Any:
        from pasta.config import section

        return section(self.cfg, "check")

    @property
    def planner_name(self) -> str:
        return str(self.cfg.planner.name)

    def skeleton(self, instance: Any) -> tuple[str, ...] | None:
        """The skill sequence the planner must use on ``instance`` (``skeleton=``), or ``None`` (it searches)."""
        from pasta.config import split_names

        names = split_names(self.cfg.skeleton, "skeleton")
        if names == ["task"]:
            return tuple(instance.skeleton[: self.horizon])
        return tuple(names) or None

    def describe(self) -> dict[str, Any]:
        """What a result row records about the run: the method's resolved settings (the whole run config),
        the models and skills used, and how the feasibility networks were trained."""
        from omegaconf import OmegaConf

        chain = self.method in NO_PLANNER
        return {"task": self.task.name, "method": self.method,
                "planner": None if chain else self.planner_name,
                "controller": {"oracle": "heuristic", "trajopt": "trajopt"}.get(self.method, self.exe.controller),
                "horizon": self.horizon, "models": str(self.models),
                "skills": list(self.task.skeleton) if chain else [sk.name for sk in self.skills],
                "scene": self.skill_choice.record() if self.skill_choice is not None else None,
                "weights": self.weights_record(),
                "config": OmegaConf.to_container(self.cfg, resolve=True),
                "feasibility_training": self.feasibility_training()}

    def weights_record(self) -> dict[str, str]:
        """The checkpoints this session plans and acts with, each as the first 16 hex digits of the SHA-256 of its
        ``model.safetensors`` (``encoder``, ``cost``, ``feasibility/<skill>``, ``policy/<skill>``): a result row
        then says which weights made it, and a row made with weights since replaced can be told apart."""
        from pasta.io.checkpoint import weights_digest
        from pasta.weights import module_dir

        if self.method in (*NO_PLANNER, "flat"):
            return {}
        dirs = {"encoder": self.cfg.encoder.weights, "cost": self.cfg.cost_model.weights}
        for sk in self.skills:
            dirs[f"feasibility/{sk.name}"] = module_dir(self.models, f"feasibility/{sk.name}")
            if self.exe.controller == "learned":
                dirs[f"policy/{sk.name}"] = module_dir(self.models, f"policy/{sk.name}")
        return {name: digest for name, digest in ((n, weights_digest(d)) for n, d in dirs.items()) if digest}

    def feasibility_training(self) -> dict[str, dict[str, Any]]:
        """Per planned skill, the negatives its attached feasibility network was trained with
        (``hard_per_positive``, ``shift_per_positive`` of its checkpoint; skills without one are left out), so a
        summary tells an ablation's networks (e.g. no hard negatives) from the shipped ones."""
        out: dict[str, dict[str, Any]] = {}
        if self.method in NO_PLANNER:
            return out
        for sk in self.skills:
            train = getattr(getattr(sk, "feasibility_model", None), "train_settings", None)
            if train is not None:
                out[sk.name] = {k: train[k] for k in ("hard_per_positive", "shift_per_positive") if k in train}
        return out

    def plan(self, seed: int, *, sim: Any = None, planning_seed: int | None = None, **perception: Any) -> Any:
        """Perceive and plan the task instance ``seed`` without executing it: the
        :class:`~pasta.execute.episode.Perceived` of :func:`~pasta.execute.episode.perceive_and_plan` (as
        :meth:`episode` plans it; ``planning_seed`` draws other samples, ``perception`` overrides fields of
        ``perception.*``)."""
        import dataclasses

        inst = self.task.instance(seed)
        sim = sim if sim is not None else self.task.make_sim()
        sim.set_state(inst.init)
        return self.plan_clouds(sim.observe().dough, inst.goal, seed=seed if planning_seed is None else planning_seed,
                                skeleton=self.skeleton(inst),
                                perception=dataclasses.replace(self.perception, **perception))

    def plan_clouds(self, obs: Any, goal: Any, *, seed: int = 0, horizon: int | None = None,
                    skeleton: Sequence[str] | None = None, perception: Any = None) -> Any:
        """Perceive ``obs (P, 3)`` and ``goal (G, 3)`` and plan with this session's models, planner and checks
        (:func:`~pasta.execute.episode.perceive_and_plan`); ``horizon`` (default the session's), ``skeleton``
        and ``perception`` (default the session's ``perception.*``) as given."""
        from pasta.execute.episode import perceive_and_plan

        return perceive_and_plan(obs, goal, planner=self.planner, planner_name=self.planner_name, skills=self.skills,
                                 encoder=self.encoder, cost=self.cost, horizon=int(horizon or self.horizon), seed=seed,
                                 skeleton=skeleton, perception=perception or self.perception, check=self.check)

    def replanner(self, goal: Any, *, seed: int = 0) -> Any:
        """The closed loop's re-planner for ``goal (G, 3)`` with this session's models, planner and checks
        (:func:`~pasta.execute.episode.replanner`)."""
        from pasta.execute.episode import replanner

        return replanner(goal, seed=seed, planner=self.planner, planner_name=self.planner_name, skills=self.skills,
                         encoder=self.encoder, cost=self.cost, perception=self.perception, check=self.check)

    def episode(self, seed: int, *, logger: Any = None, sim: Any = None) -> EpisodeOutcome:
        """Plan and execute the task instance ``seed`` (generated and cached on first use) and score it."""
        from pasta.execute.episode import run_episode

        inst = self.task.instance(seed)
        sim = sim if sim is not None else self.task.make_sim()
        if self.method == "oracle":
            from pasta.tasks.oracle import run_oracle

            res = run_oracle(self.task, inst, sim=sim)
            return EpisodeOutcome(self.task.name, self.method, seed, float(res.score.improvement),
                                  bool(res.score.success), execute_s=res.wall_s, final_dough=sim.observe().dough)
        if self.method == "trajopt":
            from pasta.config import section
            from pasta.execute.trajopt import run_trajopt

            opt = run_trajopt(self.task, inst, section(self.cfg, "trajopt"), sim=sim, seed=seed)
            info = {"trajopt": {"losses": [round(v, 8) for v in opt.losses], "best_iteration": opt.best_iteration,
                                "improvements": [round(v, 4) for v in opt.improvements],
                                "skills": [s.skill for s in opt.segments]}}
            return EpisodeOutcome(self.task.name, self.method, seed, float(opt.score.improvement),
                                  bool(opt.score.success), plan_s=opt.optimise_s, execute_s=opt.execute_s,
                                  final_dough=sim.observe().dough, info=info)
        sim.set_state(inst.init)
        episode = run_episode(sim, inst.goal, planner=self.planner, planner_name=self.planner_name, skills=self.skills,
                              encoder=self.encoder, cost=self.cost, horizon=self.horizon, seed=seed,
                              skeleton=self.skeleton(inst), cfg=self.exe, perception=self.perception,
                              check=self.check, emd_points=self.task.config.emd_points,
                              emd_seed=self.task.config.emd_seed, logger=logger, disturb=str(self.cfg.get("disturb", "")))
        score = self.task.score(episode.result.final_dough, inst)
        plan_s = float(episode.plan.timings.get("total", 0.0))
        exec_s = float(sum(s.wall_s for s in episode.result.steps))
        return EpisodeOutcome(self.task.name, self.method, seed, float(score.improvement), bool(score.success),
                              plan=episode.plan, result=episode.result, plan_s=plan_s, execute_s=exec_s,
                              final_dough=episode.result.final_dough)


def as_overrides(settings: Mapping[str, Any], prefix: str = "") -> list[str]:
    """Nested settings as ``key=value`` items: ``{"execute": {"controller": "learned"}}`` ->
    ``["execute.controller=learned"]`` (a value that is a plugin name for a group key stays a switch)."""
    out = []
    for key, value in settings.items():
        full = f"{prefix}{key}"
        if isinstance(value, Mapping):
            out += as_overrides(value, f"{full}.")
        else:
            out.append(f"{full}={'' if value is None else value}")
    return out


def build_session(task: str | None = None, overrides: Sequence[str] = (), *, plugins: Any = None,
                  **settings: Any) -> Session:
    """Load a method's models and planner for a task, from one resolved run config.

    Args:
        task: the task name (or give ``task=NAME`` in ``overrides``).
        overrides: ``key=value`` items of the run config (``pasta config`` lists them).
        settings: the same as keyword arguments, nested sections as dicts:
            ``build_session("crs", execute={"controller": "learned"}, planner="sampling")``.

    Raises:
        ConfigError: a bad setting, or the task's ground-truth chain needs a skill that is not chosen.
    """
    from pasta.config import load_config, section, split_names
    from pasta.plugins import get_plugins
    from pasta.weights import models_root, weight_overrides

    plugins = plugins or get_plugins()
    items = ([f"task={task}"] if task else []) + list(overrides) + as_overrides(settings)
    given = {i.partition("=")[0].strip() for i in items}
    if "task" not in given:
        raise ConfigError("a session needs a task: task=NAME (e.g. task=crs)")
    probe = load_config(items, plugins=plugins)
    root = models_root(probe.models)
    if probe.method != "flat":  # the encoder and cost weights under the models root, unless set explicitly
        items += weight_overrides(root, items)
    cfg = load_config(items, plugins=plugins)
    name = str(cfg.task.name)
    skill_configs = {n: section(cfg, f"skill.{n}") for n in (cfg.get("skill") or {})}
    task_obj = plugins.tasks.load(name)(section(cfg, "task"), section(cfg, "sim"), skill_configs=skill_configs)
    steps = split_names(cfg.skeleton, "skeleton")
    given_steps = steps if steps != ["task"] else []  # a given skeleton sets the horizon (as in `pasta plan`)
    horizon = int(cfg.horizon or len(given_steps) or task_obj.horizon)
    if steps == ["task"] and horizon > task_obj.horizon:
        raise ConfigError(f"horizon={horizon}: skeleton=task plans the task's {task_obj.horizon}-step chain "
                          f"({','.join(task_obj.skeleton)}); omit horizon= or give horizon<={task_obj.horizon}")
    session = Session(task_obj, cfg, root, horizon)
    if cfg.method in NO_PLANNER:
        return session
    from pasta.execute.skillset import choose_skills, needs_feasibility_network

    from pasta.tasks.scene import floor_height, resolve_scene

    exe = section(cfg, "execute")
    scene = resolve_scene(task_obj.scene(), floor_height(int(cfg.sim.n_grid)), plugins)
    choice = choose_skills(split_names(cfg.skills, "skills") or None, root, plugins=plugins,
                           policy=exe.controller == "learned", flat=cfg.method == "flat", scene=scene)
    choice.require(task_obj.skeleton, f"task '{name}' (its ground-truth chain)")
    chosen = [task_obj.skill(n) for n in choice.names]
    if exe.controller == "learned":
        from pasta.policy import POLICY_DIR
        from pasta.policy.learned import load_policy
        from pasta.weights import module_dir

        for s in chosen:
            load_policy(module_dir(root, f"{POLICY_DIR}/{s.name}"), s, device=str(cfg.device))
    if cfg.method == "flat":
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
