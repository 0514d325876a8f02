"""Single-skill evaluation: learned policy vs heuristic controller vs scripted expert.

A *config* is an initial scene (the skill's demonstration scene, :meth:`pasta.core.Skill.demo_scene`)
and expert parameters, drawn from a seed that the training demonstrations did not use. Its goal is what the scripted expert makes of the scene (the simulator is
deterministic): the observed dough after the expert's run. A skill without a scripted expert
(:meth:`pasta.core.Skill.has_gbto`) gets its goal as its demonstrations do: trajectory optimisation toward a
target its ``demo_target`` draws (:func:`pasta.tasks.step.gbto_expert`, the skill's budget), and the
"expert" column replays the optimised actions. Each controller then starts from the same
initial state with that goal cloud as its sub-goal, and is scored by the normalised improvement
``(EMD_0 - EMD_T) / EMD_0`` of the observed dough to the goal. The expert's own score is its
reproducibility (1 for a deterministic simulator).

``pasta train evaluate [models=DIR] [n=20] [seed=1000] [skills=a,b] [controllers=learned,heuristic,expert]
[scene=VARIANT] [done_threshold=T] [min_steps=M] [max_steps=C] [reset=false] [start_step=S] [json=FILE]``
(:class:`EvaluateConfig`; ``models``: default the shipped weights) prints the table of docs/policies.md. The
learned controller's stopping rule is the checkpoint's own (``config.controller``) unless given; a learned reset
pose beside the policy (``reset.*``) is used unless ``reset=false``. The simulator is configured as ``pasta demos``
configures it (5,000 particles, 1,000 observed); ``scene``: a demonstration scene variant every listed skill has,
e.g. ``skills=push scene=wide``, ``skills=roll scene=board``.
"""

from __future__ import annotations

import sys
import time
import zlib
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from pasta.core.errors import ConfigError
from pasta.core.metrics import emd, normalized_improvement
from pasta.core.files import write_json

__all__ = ["EvaluateConfig", "SkillConfig", "evaluate_command", "evaluate_config", "evaluate_skill", "make_configs",
           "table"]

CONTROLLERS = ("learned", "heuristic", "expert")
#: the most configs per skill ``n=`` asks for (each is a simulated episode per controller)
MAX_CONFIGS = 10_000


@dataclass
class SkillConfig:
    """One held-out single-skill config: the initial simulator state, the expert's params, its index, and for a
    skill without a scripted expert the seed of its goal's trajectory optimisation."""

    skill: str
    seed: int
    state: Any
    params: dict[str, float]
    goal_seed: int = 0
    optimised: Any = None

    def expert(self, sim: Any, skill: Any) -> tuple[Any, Any, int | None]:
        """``(approach pose, a fresh expert controller, its step limit)`` of this config, ``sim`` at :attr:`state`:
        the skill's scripted expert with :attr:`params` (limit: the skill's), or for a skill without one the
        actions that trajectory optimisation finds toward a target drawn from :attr:`goal_seed`, replayed in
        full (optimised on the first call, kept in :attr:`optimised`; ``sim`` is left as it was)."""
        from pasta.tasks.step import Replay, gbto_expert

        piece = sim.observe().dough
        if not type(skill).goals_by_trajopt():
            return skill.expert_approach_pose(piece, self.params, scene=piece), skill.expert(self.params), None
        if self.optimised is None:
            _, approach, replay = gbto_expert(sim, skill, piece, np.arange(len(piece)),
                                              np.random.default_rng(self.goal_seed))
            self.optimised = (approach, replay.actions)
        approach, actions = self.optimised
        return approach, Replay(actions), len(actions)


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
        params: dict[str, float] = {}
        goal_seed = 0
        if type(skill).goals_by_trajopt():
            goal_seed = int(rng.integers(2**31))
        else:
            params = {k: float(v) for k, v in skill.sample_expert_params(sim.observe().dough, rng).items()}
        out.append(SkillConfig(skill.name, i, sim.get_state(), params, goal_seed))
    return out


def _run(sim: Any, skill: Any, controller: Any, goal: np.ndarray | None, approach: Any = None,
         max_steps: int | None = None) -> tuple[int, bool]:
    from pasta.tasks.step import run_skill

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
        approach, expert, limit = cfg.expert(sim, skill)
        _run(sim, skill, expert, None, approach, max_steps=limit)
        goal = sim.observe().dough
        emd0 = emd(piece, goal, n=emd_points, seed=cfg.seed)
        for name in controllers:
            sim.set_state(start)
            t0 = time.perf_counter()
            try:
                if name == "expert":
                    approach, expert, limit = cfg.expert(sim, skill)
                    steps, done = _run(sim, skill, expert, None, approach, max_steps=limit)
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
            if recs.get(c):
                v = np.array([r["ni"] for r in recs[c]])
                means[c] = float(v.mean())
                cells.append(f"{v.mean():.3f} ({v.std():.3f})")
            else:
                cells.append("-")
        ratio = f"{means['learned'] / means['expert']:.2f}" if "learned" in means and means.get("expert") else "-"
        n = max(len(r) for r in recs.values())
        lines.append(f"| {skill} | {n} | " + " | ".join(cells) + f" | {ratio} |")
    return "\n".join(lines)


@dataclass
class SkillRunSettings:
    """What ``pasta train evaluate`` and ``pasta train select`` share: how a learned policy starts and stops, and
    the single-skill simulator they run it in (the one ``pasta demos`` makes).

    Attributes:
        start_step: the step counter at a learned reset pose (negative: the regressor's own ``start_step``).
        reset: use a learned reset pose beside the policy (``reset.*``) when there is one.
        learned_max_steps: step limit of the learned controller (0: the skill's own).
        n_particles, obs_points: simulator particles and observed points (``pasta demos``'s 5,000 and 1,000).
        n_grid, max_particles: the simulator's grid and particle capacity (64 and 10,000, as ``pasta demos``).
    """

    start_step: int = -1
    reset: bool = True
    learned_max_steps: int = 0
    n_particles: int = 5000
    obs_points: int = 1000
    n_grid: int = 64
    max_particles: int = 10000

    def __post_init__(self) -> None:
        from pasta.config.validate import check_int

        check_int(self.start_step, "start_step", low=-1)
        check_int(self.learned_max_steps, "learned_max_steps", low=0)
        self.sim_config()  # the simulator's own checks (particles, grid), before any simulator starts

    def sim_config(self) -> Any:
        """The single-skill simulator's :class:`pasta.sim.SimConfig` (the one ``pasta demos`` makes)."""
        from pasta.sim import SimConfig

        try:
            return SimConfig(n_particles=self.n_particles, obs_points=self.obs_points, n_grid=self.n_grid,
                             max_particles=max(self.max_particles, self.n_particles))
        except (TypeError, ValueError) as exc:
            raise ConfigError(str(exc).removeprefix("sim.")) from None

    def policy_options(self) -> dict[str, Any]:
        """``load_policy`` keywords for ``start_step`` and ``reset`` (what is not the checkpoint's own)."""
        return {**({"start_step": self.start_step} if self.start_step >= 0 else {}),
                **({} if self.reset else {"reset": False})}  # reset=False: ignore a learned reset pose

    def make_sim(self) -> Any:
        """The single-skill simulator, with every registered simulated tool."""
        from pasta.plugins import get_plugins
        from pasta.sim import Simulator

        return Simulator(self.sim_config(), tools=get_plugins().simulated_tools())


@dataclass
class EvaluateConfig(SkillRunSettings):
    """Settings of ``pasta train evaluate`` (:func:`evaluate_command`).

    Attributes:
        models: models root whose ``policy/<skill>`` the learned controller loads (empty: the shipped weights).
        n: configs per skill.
        seed: base seed of their stream (1000: the test configs; 2000: validation; ``pasta demos`` uses 0).
        skills: comma-separated skills (empty: every registered skill that can make demonstrations).
        controllers: comma-separated, of ``learned``, ``heuristic``, ``expert``.
        scene: a demonstration scene variant every listed skill has (e.g. ``skills=push scene=wide``).
        done_threshold, min_steps, max_steps: the learned controller's stopping rule (negative: the
            checkpoint's own, ``config.controller``).
        start_step, reset, learned_max_steps, n_particles, obs_points, n_grid, max_particles: :class:`SkillRunSettings`.
        threads: torch CPU threads.
        json: write the per-config records to this file (empty: none).
    """

    models: str = ""
    n: int = 20
    seed: int = 1000
    skills: str = ""
    controllers: str = ",".join(CONTROLLERS)
    scene: str = "default"
    done_threshold: float = -1.0
    min_steps: int = -1
    max_steps: int = -1
    threads: int = 1
    json: str = ""

    def __post_init__(self) -> None:
        from pasta.config.validate import check_int, check_number, check_seed, check_threads

        super().__post_init__()
        check_int(self.n, "n", low=1, high=MAX_CONFIGS)
        check_seed(self.seed, "seed")
        if not self.done_threshold < 0:  # negative: the checkpoint's own rule
            check_number(self.done_threshold, "done_threshold", high=1.0)
        check_int(self.min_steps, "min_steps", low=-1)
        check_int(self.max_steps, "max_steps", low=-1)
        check_threads(self.threads, "threads")

    def skill_names(self) -> list[str]:
        """``skills=`` as names (empty: every registered skill that can make demonstrations and, when the learned
        controller is scored, has a trained policy: an installed plugin without one is left out)."""
        from pasta.demos import demo_skills
        from pasta.io.checkpoint import checkpoint_exists

        given = [s.strip() for s in str(self.skills).split(",") if s.strip()]
        if given or "learned" not in self.controller_names():
            return given or demo_skills()
        return [name for name in demo_skills() if checkpoint_exists(self.policy_dir(name))]

    def policy_dir(self, skill: str) -> Any:
        """Where ``skill``'s policy is: under ``models=`` or, where that root has none, the shipped one
        (:func:`pasta.weights.module_dir`)."""
        from pasta.policy import POLICY_DIR
        from pasta.weights import models_root, module_dir

        return module_dir(models_root(self.models), f"{POLICY_DIR}/{skill}")

    def controller_names(self) -> list[str]:
        return [c.strip() for c in str(self.controllers).split(",") if c.strip()]


def evaluate_config(overrides: dict[str, Any] | None = None) -> EvaluateConfig:
    """:class:`EvaluateConfig` from ``key=value`` overrides, every value checked before any simulator starts:
    the skills (registered, able to make demonstrations, with scene ``scene``), the controllers, the learned
    policies under ``models`` when ``learned`` is one of them, and the ``json`` file."""
    from pasta.config.overrides import build
    from pasta.config.validate import check_output_file
    from pasta.core.errors import did_you_mean
    from pasta.demos.scene import check_demo_skill, check_variant
    from pasta.io.checkpoint import checkpoint_exists

    cfg = build(EvaluateConfig, dict(overrides or {}), command="pasta train evaluate")
    controllers = cfg.controller_names()
    if not controllers:
        raise ConfigError(f"controllers={cfg.controllers}: names no controller; choose of {', '.join(CONTROLLERS)}")
    for c in controllers:
        if c not in CONTROLLERS:
            raise ConfigError(f"unknown controller '{c}'{did_you_mean(c, CONTROLLERS)}; "
                              f"choose of {', '.join(CONTROLLERS)}")
    for name in cfg.skill_names():
        check_variant(check_demo_skill(name), cfg.scene)
        policy = cfg.policy_dir(name)
        if "learned" in controllers and not checkpoint_exists(policy):
            raise ConfigError(f"controllers=learned: no trained policy of {name} in {policy}; train it with "
                              f"`pasta train policy skill={name} data=DIR out=MODELS` and give models=MODELS")
    if cfg.json:
        check_output_file(cfg.json, "json")
    return cfg


def evaluate_command(overrides: dict[str, Any] | None = None) -> dict[str, dict[str, list[dict[str, Any]]]]:
    """``pasta train evaluate [key=value ...]`` as a function (:class:`EvaluateConfig` keys): score the
    controllers on held-out single-skill configs; returns ``{skill: {controller: [per-config records]}}``
    (:func:`table` prints them as docs/policies.md does)."""
    from pasta.demos.generate import skill_config
    from pasta.plugins import get_plugins
    from pasta.policy.learned import load_policy
    from pasta.train.loop import torch_threads

    cfg = evaluate_config(overrides)
    names, controllers = cfg.skill_names(), cfg.controller_names()
    kw: dict[str, Any] = {k: getattr(cfg, k) for k in ("min_steps", "max_steps") if getattr(cfg, k) >= 0}
    if cfg.done_threshold >= 0:
        kw["done_threshold"] = cfg.done_threshold
    kw.update(cfg.policy_options())
    results = {}
    with torch_threads(cfg.threads):
        sim = cfg.make_sim()
        for name in names:
            skill = get_plugins().skills.create(name, skill_config(name, cfg.scene))
            if "learned" in controllers:
                load_policy(cfg.policy_dir(name), skill, **kw)
            own = [c for c in controllers if c != "heuristic" or type(skill).has_controller()]
            if len(own) < len(controllers):
                print(f"{name}: no heuristic controller (its plugin defines none); scoring {', '.join(own)}",
                      file=sys.stderr)
            results[name] = evaluate_skill(sim, skill, make_configs(skill, sim, cfg.n, cfg.seed, scene=cfg.scene),
                                           own, learned_max_steps=cfg.learned_max_steps or None)
    if cfg.json:
        write_json(cfg.json, results, indent=1)
    return results
