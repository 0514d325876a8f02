"""Conformance checkers for plugins (in the spirit of Gymnasium's ``check_env``).

Each ``check_*`` raises :class:`PluginConformanceError` naming the first broken rule, and returns
quietly otherwise. The contract classes of :mod:`pasta.testing` wrap them for pytest.
"""

from __future__ import annotations

import math
from typing import Any

import torch

from pasta.core import (
    CardinalityError,
    Controller,
    Encoder,
    MissingComponentError,
    Plan,
    Planner,
    PlanningProblem,
    Skill,
    SkillSpec,
    Task,
    check_skeleton,
    kept_indices,
)
from pasta.core.errors import PastaError
from pasta.core.plan import as_latents
from pasta.planning import rollout


class PluginConformanceError(PastaError, AssertionError):
    """A plugin breaks its contract."""


def _latents_close(given: Any, expected: torch.Tensor, atol: float) -> bool:
    try:
        return torch.allclose(torch.tensor(given, dtype=expected.dtype), expected.detach().cpu(), atol=atol)
    except (TypeError, ValueError, RuntimeError):  # wrong nesting or shape
        return False


def _require(cond: bool, message: str) -> None:
    if not cond:
        raise PluginConformanceError(message)


def check_skill(skill: Skill, *, latent_dim: int = 5, batch: int = 7, seed: int = 0) -> None:
    """Check a skill's spec, feasibility shape/range/permutation invariance, its hooks' errors, and for a skill with
    ``demo_target`` the targets it draws.

    Feasibility is only exercised when a model is attached (or the skill overrides ``feasibility``);
    otherwise it must raise :class:`MissingComponentError` naming the skill.
    """
    _require(isinstance(skill, Skill), f"{skill!r} is not a pasta.core.Skill")
    _require(isinstance(skill.spec, SkillSpec), f"{type(skill).__name__}.spec is not a SkillSpec")
    gen = torch.Generator().manual_seed(seed)
    u_in = torch.randn(batch, skill.n_in, latent_dim, generator=gen)
    u_out = torch.randn(batch, skill.n_out, latent_dim, generator=gen)
    try:
        f = skill.feasibility(u_in, u_out)
    except MissingComponentError as exc:
        _require(skill.name in str(exc), f"skill '{skill.name}': MissingComponentError must name the skill, got {exc}")
    else:
        _require(tuple(f.shape) == (batch,), f"skill '{skill.name}': feasibility must return (B,) = ({batch},), got {tuple(f.shape)}")
        _require(bool(((f >= 0) & (f <= 1)).all()), f"skill '{skill.name}': feasibility must lie in [0, 1]")
        f_perm = skill.feasibility(u_in.flip(1), u_out.flip(1))
        _require(torch.allclose(f, f_perm, atol=1e-5), f"skill '{skill.name}': feasibility must be invariant to entity order")
    for hook in ("controller", "policy"):
        try:
            ctrl = getattr(skill, hook)()
        except MissingComponentError:
            continue
        _require(isinstance(ctrl, Controller), f"skill '{skill.name}': {hook}() must return a pasta.core.Controller")
    if type(skill).has_gbto():
        _check_demo_target(skill)


def _check_demo_target(skill: Skill) -> None:
    """A skill taught by trajectory optimisation (``demo_scene`` and ``demo_target``): for its demo scene the target
    is a finite ``(G, 3)`` cloud, the same for the same random stream and different from the scene (a target equal
    to the scene teaches nothing), and the approach pose toward it is finite."""
    import numpy as np

    from pasta.demos.scene import scene_particles

    rng = np.random.default_rng(0)
    dough = scene_particles(skill.demo_scene(rng, 0.02), 1500, rng)[0].astype(np.float32)
    targets = [np.asarray(skill.demo_target(dough, np.random.default_rng(seed))) for seed in (1, 1)]
    where = f"skill '{skill.name}': demo_target"
    t = targets[0]
    _require(t.ndim == 2 and t.shape[1] == 3 and len(t) > 0, f"{where} must return a (G, 3) cloud, got {t.shape}")
    _require(bool(np.isfinite(t).all()), f"{where} returned non-finite points")
    _require(np.array_equal(targets[0], targets[1]), f"{where} must draw every random number from its rng")
    _require(t.shape != dough.shape or float(np.abs(t - dough).max()) > 1e-3,
             f"{where} returned the scene itself: nothing for the optimiser to do")
    try:
        pose = skill.approach_pose(dough, t, scene=dough)  # type: ignore[call-arg]  # beyond the contract
    except TypeError:  # the two-argument contract signature
        pose = skill.approach_pose(dough, t)
    _require(bool(np.isfinite(np.asarray(pose.position, float)).all()) and bool(np.isfinite(pose.yaw)),
             f"skill '{skill.name}': approach_pose toward its demo target is not finite: {pose}")


def check_encoder(encoder: Encoder, *, num_points: int = 64, seed: int = 0) -> None:
    """Check encode/decode/prior shapes, finiteness, and that ``clamp`` keeps ``t`` in the box."""
    d = encoder.latent_dim
    _require(d == encoder.z_dim + 3, f"encoder: latent_dim must be z_dim + 3, got {d}")
    gen = torch.Generator().manual_seed(seed)
    prior = encoder.sample_prior(4, gen)
    _require(tuple(prior.shape) == (4, d), f"encoder: sample_prior(4) must be (4, {d}), got {tuple(prior.shape)}")
    clouds = encoder.decode(prior, num_points)
    _require(tuple(clouds.shape) == (4, num_points, 3), f"encoder: decode must give (K, P, 3), got {tuple(clouds.shape)}")
    codes = encoder.encode(clouds)
    _require(tuple(codes.shape) == (4, d), f"encoder: encode must give (K, D), got {tuple(codes.shape)}")
    _require(bool(codes.isfinite().all()), "encoder: encode returned non-finite values")
    far = encoder.clamp(prior + 100.0)
    _require(bool((far[:, encoder.z_dim :] <= torch.tensor(encoder.t_high) + 1e-6).all()), "encoder: clamp must bound t")


def check_plan(plan: Plan, problem: PlanningProblem, *, cost_weight: float | None = None, atol: float = 1e-4) -> None:
    """Check a plan is well formed for ``problem`` and that its numbers match the problem's models."""
    _require(isinstance(plan, Plan), f"planner returned {type(plan).__name__}, not a Plan")
    skills = problem.skill_map
    _require(all(n in skills for n in plan.skills), f"plan uses unknown skills {plan.skills}; the problem's skills are {list(skills)}")
    _require(len(plan.steps) == problem.horizon, f"plan has {len(plan.steps)} steps, horizon is {problem.horizon}")
    _require(plan.seed == problem.seed, f"plan.seed is {plan.seed!r}, the problem's seed is {problem.seed!r}")
    for field, given, expected in (("initial", plan.initial, problem.obs), ("goal", plan.goal, problem.goal)):
        _require(_latents_close(given, expected, atol), f"plan.{field} {given} differs from the problem's "
                 f"{'observed' if field == 'initial' else 'goal'} latents {as_latents(expected)}")
    if problem.skeleton is not None:
        _require(tuple(plan.skills) == tuple(problem.skeleton),
                 f"plan skeleton {list(plan.skills)} ignores the given problem.skeleton {list(problem.skeleton)}")
    try:
        check_skeleton(plan.skills, [s.spec for s in problem.skills], len(problem.obs), len(problem.goal))
    except CardinalityError as exc:
        raise PluginConformanceError(f"plan skeleton is not cardinality-consistent: {exc}") from None
    k, d = len(problem.obs), problem.encoder.latent_dim
    for h, step in enumerate(plan.steps):
        spec = skills[step.skill].spec
        _require(len(step.inputs) == spec.n_in, f"step {h}: {step.skill} consumes {spec.n_in} entities, attention has {len(step.inputs)}")
        kept_indices(k, step.inputs)
        _require(len(step.subgoal) == spec.n_out and all(len(r) == d for r in step.subgoal), f"step {h}: subgoal must be ({spec.n_out}, {d})")
        k += spec.delta
        _require(len(step.state) == k, f"step {h}: state must have {k} entities, has {len(step.state)}")
        _require(0.0 <= step.feasibility <= 1.0, f"step {h}: feasibility {step.feasibility} outside [0, 1]")
    _require(math.isfinite(plan.final_cost) and plan.final_cost >= -atol, f"final cost {plan.final_cost} must be finite and >= 0")
    subgoals = [torch.tensor(s.subgoal, dtype=problem.obs.dtype).unsqueeze(0) for s in plan.steps]
    with torch.no_grad():
        again = rollout(problem, plan.skills, [s.inputs for s in plan.steps], subgoals)
    for h, step in enumerate(plan.steps):
        _require(abs(float(again.feasibility[0, h]) - step.feasibility) <= atol, f"step {h}: reported feasibility {step.feasibility} differs from the model's {float(again.feasibility[0, h])}")
        _require(torch.allclose(again.states[h][0], torch.tensor(step.state, dtype=problem.obs.dtype), atol=atol),
                 f"step {h}: reported state {step.state} differs from the rolled-out set {as_latents(again.states[h][0])}")
    _require(abs(float(again.cost[0]) - plan.final_cost) <= atol, f"reported final cost {plan.final_cost} differs from the model's {float(again.cost[0])}")
    if cost_weight is not None:
        floor_prod = math.prod(max(s.feasibility, 0.01) for s in plan.steps)
        bound = floor_prod * math.exp(-cost_weight * max(plan.final_cost, 0.0))
        _require(plan.score <= bound + atol, f"score {plan.score} exceeds the objective's value {bound} (feasibilities "
                 f"{[s.feasibility for s in plan.steps]}, cost {plan.final_cost}, cost_weight {cost_weight})")
    _require(bool(plan.to_json()) and Plan.from_json(plan.to_json()).to_json() == plan.to_json(), "plan does not survive a JSON round trip")


def check_planner(planner: Planner, problem: PlanningProblem | None = None, *, name: str | None = None) -> Plan:
    """Run ``planner`` on ``problem`` (default: the analytic problem) and check the plan, determinism and errors.

    Also checks that ``plan.planner`` is ``name`` (default: the class's ``name``), and that the planner
    honours a given ``problem.skeleton`` (a sub-optimal one on the analytic problem) and records the seed.
    """
    from pasta.testing._analytic import analytic_problem

    _require(isinstance(planner, Planner), f"{planner!r} is not a pasta.core.Planner")
    expected_name = name or getattr(type(planner), "name", None)
    problem = problem or analytic_problem()
    cost_weight = getattr(planner.config, "cost_weight", None)
    plan = planner.plan(problem)
    check_plan(plan, problem, cost_weight=cost_weight)
    _require(plan.planner == expected_name, f"plan.planner is {plan.planner!r}, the planner is registered as {expected_name!r}")
    again = planner.plan(problem)
    _require(plan.to_json(timings=False) == again.to_json(timings=False), "the same seed must give the same plan (JSON without timings)")
    given = analytic_problem(skeleton=("move", "split", "flatten"), seed=problem.seed + 1)
    check_plan(planner.plan(given), given, cost_weight=cost_weight)  # seed, skeleton honoured
    impossible = analytic_problem(horizon=1, goal=problem.goal.new_zeros(3, problem.encoder.latent_dim) + 0.5)
    try:
        planner.plan(impossible)
    except CardinalityError:
        pass
    else:
        raise PluginConformanceError("a problem no skill sequence can solve must raise CardinalityError")
    return plan


def check_task(task: Task, *, skills: Any = None, seed: int = 1000) -> Any:
    """Check a task's metadata, one instance (``task.instance(seed)``: cached when the task keeps a cache) and
    its scoring; return the instance.

    Checks: ``task`` is a :class:`pasta.core.Task` with a name, a non-empty skeleton of registered skills
    (``skills``: a registry, default the registered skills) and a threshold in ``(0, 1]``; its scene allows its
    skeleton, and the static tools standing in the instance are those the scene declares; the instance
    records the seed and the skeleton; initial and goal clouds are finite ``(P, 3)`` of the same ``P`` and
    differ; the goal scored against itself is a success with improvement 1 and the initial dough scores 0.
    """
    import numpy as np

    _require(isinstance(task, Task), f"{task!r} is not a pasta.core.Task")
    name = task.name
    _require(isinstance(name, str) and bool(name), f"{type(task).__name__}.name must be the registered name, got {name!r}")
    if skills is None:
        from pasta.plugins.registry import get_plugins

        skills = get_plugins().skills
    skeleton = tuple(task.skeleton)
    _require(bool(skeleton) and all(isinstance(n, str) for n in skeleton), f"task '{name}': skeleton must be a non-empty tuple of skill names, got {skeleton!r}")
    unknown = [n for n in skeleton if n not in skills]
    _require(not unknown, f"task '{name}': skeleton {list(skeleton)} uses unregistered skills {unknown}; registered: {skills.names()}")
    _require(task.horizon == len(skeleton), f"task '{name}': horizon {task.horizon} differs from len(skeleton) = {len(skeleton)}")
    threshold = float(task.threshold)
    _require(0.0 < threshold <= 1.0, f"task '{name}': threshold must lie in (0, 1], got {threshold}")
    _check_task_scene(task, skeleton, skills)
    inst = task.instance(seed)
    _check_instance_scene(task, inst)
    _require(int(inst.seed) == seed, f"task '{name}': instance({seed}).seed is {inst.seed}")
    _require(list(inst.skeleton) == list(skeleton), f"task '{name}' seed {seed}: the instance's chain {list(inst.skeleton)} differs from the task's skeleton {list(skeleton)}")
    init, goal = np.asarray(inst.init_points), np.asarray(inst.goal)
    for what, cloud in (("init_points", init), ("goal", goal)):
        _require(cloud.ndim == 2 and cloud.shape[1] == 3 and len(cloud) > 0, f"task '{name}' seed {seed}: {what} must be (P, 3), got {cloud.shape}")
        _require(bool(np.isfinite(cloud).all()), f"task '{name}' seed {seed}: {what} has non-finite values")
    _require(init.shape == goal.shape, f"task '{name}' seed {seed}: init_points {init.shape} and goal {goal.shape} must be the same particles")
    moved = float(np.abs(goal - init).max())
    _require(moved > 0.0, f"task '{name}' seed {seed}: the goal equals the initial dough (no particle moved)")
    itself = task.score(goal, inst)
    _require(itself.success and abs(itself.improvement - 1.0) < 1e-6 and itself.emd_final < 1e-9,
             f"task '{name}' seed {seed}: the goal scored against itself must succeed with improvement 1, got {itself}")
    start = task.score(init, inst)
    _require(not start.success and abs(start.improvement) < 1e-6,
             f"task '{name}' seed {seed}: the initial dough must score improvement 0 (no success), got {start}")
    return inst


def _check_task_scene(task: Task, skeleton: tuple[str, ...], skills: Any) -> None:
    """The task's scene is a :class:`pasta.core.Scene` of registered static tools that lets its own chain run."""
    from pasta.core import Scene
    from pasta.tasks.scene import floor_height, resolve_scene, scene_fit

    name = task.name
    declared = task.scene()
    _require(isinstance(declared, Scene), f"task '{name}': scene() must return a pasta.core.Scene, got {declared!r}")
    sim_config = getattr(task, "sim_config", None)
    scene = resolve_scene(declared, floor_height(int(getattr(sim_config, "n_grid", 64))))
    unmet = scene_fit(skeleton, scene, skills)
    _require(not unmet, f"task '{name}': its scene ({scene.describe()}) does not allow its own chain: {unmet}")


def _check_instance_scene(task: Task, inst: Any) -> None:
    """Where the instance records its tools (``init.tool_names``, ``init.tools``), the static tools that stand in
    it (away from their parking place) are the ones the task's scene declares."""
    import numpy as np

    from pasta.plugins.registry import get_plugins

    names = tuple(getattr(getattr(inst, "init", None), "tool_names", ()) or ())
    if not names:
        return
    poses = np.asarray(inst.init.tools, np.float64)
    tools = get_plugins().tools
    standing = [n for i, n in enumerate(names) if n in tools and tools.info(n).spec.is_static
                and float(np.abs(poses[i, :3] - np.asarray(tools.info(n).spec.park)).max()) > 1e-6]
    declared = sorted(task.scene().static)
    _require(sorted(standing) == declared,
             f"task '{task.name}' seed {inst.seed}: static tools standing in the instance {sorted(standing)} differ from "
             f"its scene's {declared} (declare them in Task.static_tools, or override Task.scene)")


#: Search budget for conformance runs: they check a plan's structure, determinism and errors, not its quality.
SMALL_BUDGET: dict[str, Any] = {"num_samples": 32, "iterations": 10}


def small_budget(registry: Any, name: str) -> dict[str, Any]:
    """The :data:`SMALL_BUDGET` fields that ``name``'s config has (a planner may have none of them)."""
    cfg = registry.default_config(name)
    return {k: v for k, v in SMALL_BUDGET.items() if hasattr(cfg, k)}


def configured(registry: Any, name: str, overrides: dict[str, Any] | None = None) -> Any:
    """Build ``name`` from ``registry`` with its default config updated by ``overrides``."""
    cfg = registry.default_config(name)
    for key, value in (overrides or {}).items():
        if not hasattr(cfg, key):
            raise PluginConformanceError(f"{registry.kind} '{name}' config has no field '{key}'")
        setattr(cfg, key, value)
    return registry.create(name, cfg)
