"""Reusable pytest contract suites for plugin authors (hydra's ``LauncherTestSuite`` pattern).

A plugin package tests itself with a few lines::

    from pasta.testing import PlannerContract, SkillContract, TaskContract

    class TestPinch(SkillContract):
        skill_name = "pinch"

    class TestMyPlanner(PlannerContract):
        planner_name = "beam"
        planner_overrides = {"num_samples": 512}   # keep the test fast

    class TestMyTask(TaskContract):
        task_name = "stack"

``PlannerContract`` runs the planner on the analytic problem (:func:`pasta.testing.analytic_problem`),
whose optimal skill sequence and attention are known. ``TaskContract`` makes one instance of the task (through
``task.instance``, so a task with a cache generates it once) and checks it with
:func:`pasta.testing.check_task`; its tests run the simulator for built-in-style tasks, so mark the
class ``@pytest.mark.sim`` where that matters.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
import pytest

from pasta.core import Planner, Skill, SkillObservation, Task
from pasta.plugins.registry import Plugins, get_plugins
from pasta.testing._analytic import OPTIMAL_SKELETON, analytic_problem
from pasta.testing._checks import check_plan, check_planner, check_skill, check_task, configured


class SkillContract:
    """Contract tests for a registered skill."""

    skill_name: ClassVar[str]

    def plugins(self) -> Plugins:
        return get_plugins()

    def make_skill(self) -> Skill:
        return self.plugins().skills.create(self.skill_name)

    def test_registered_spec_matches_class(self) -> None:
        info = self.plugins().skills.info(self.skill_name)
        assert info.spec == info.load().spec

    def test_conforms(self) -> None:
        check_skill(self.make_skill())

    #: env steps the expert may take (it runs to its done, producing the heuristic controller's goal)
    contract_expert_steps: ClassVar[int] = 200
    #: env steps the heuristic controller runs for
    contract_controller_steps: ClassVar[int] = 5

    @pytest.mark.sim
    def test_actions_fit_tool_layout(self) -> None:
        """Run the expert (on its demo scene, or a small box of dough) and then the heuristic controller in
        the simulator; every action must fit the tool's action layout, be finite and lie in [-1, 1]."""
        skill = self.make_skill()
        cls = type(skill)
        tools = self.plugins().tools
        if skill.tool not in tools or not tools.info(skill.tool).spec.simulated:
            pytest.skip(f"tool '{skill.tool}' of skill '{skill.name}' has no geometry: nothing to simulate")
        has_controller = cls.has_controller()
        missing = set(cls.missing_demo_hooks())  # the expert runs on a small box when there is no demo scene
        has_expert = not (missing - {"demo_scene"})
        if not (has_expert or has_controller):
            pytest.skip(f"skill '{skill.name}' has neither a scripted expert nor a heuristic controller")
        from pasta.sim import SimConfig, Simulator, box_particles

        spec = tools.info(skill.tool).spec
        sim = Simulator(SimConfig(n_grid=32, max_particles=1500, n_particles=1500, obs_points=300, seed=0), tools=[spec])
        rng = np.random.default_rng(0)
        if "demo_scene" not in missing:
            from pasta.demos.scene import scene_particles

            x0 = scene_particles(skill.demo_scene(rng, sim.floor_y), 1500, rng)[0]
        else:
            x0 = box_particles((0.5, sim.floor_y + 0.04, 0.5), (0.16, 0.08, 0.07), 1500, rng)

        def run(controller: Any, approach: Any, goal: np.ndarray | None, max_steps: int, who: str) -> None:
            sim.set_tool_pose(skill.tool, approach.position, yaw=approach.yaw)
            view = None
            for step in range(max_steps):
                obs = sim.observe()
                view = SkillObservation(piece=obs.dough, goal=goal, tool_points=obs.tool_points[skill.tool],
                                        tool_pose=obs.tool_poses[skill.tool], scene=obs.dough)
                if step == 0:
                    controller.reset(view)
                action, done = controller.act(view)
                a = np.asarray(action, dtype=np.float64)
                where = f"skill '{skill.name}' {who}, step {step}: action {a.tolist()} for tool '{skill.tool}' ({', '.join(spec.channels)})"
                assert a.ndim == 1 and spec.required_action <= a.shape[0] <= spec.action_dim, f"{where}: wrong shape {a.shape}"
                assert np.isfinite(a).all(), f"{where}: not finite"
                assert np.abs(a).max(initial=0.0) <= 1.0 + 1e-6, f"{where}: outside [-1, 1]"
                if done and not a.any():
                    break
                sim.step({skill.tool: a})
                if done:
                    break

        goal = None
        if has_expert:
            sim.reset(x0, seed=0)
            piece = sim.observe().dough
            params = skill.sample_expert_params(piece, rng)
            run(skill.expert(params), skill.expert_approach_pose(piece, params, scene=piece), None,
                self.contract_expert_steps, "expert")
            for _ in range(5):
                sim.step()
            goal = sim.observe().dough.copy()
        if has_controller:
            sim.reset(x0, seed=0)
            piece = sim.observe().dough
            if goal is None:  # no expert to make a reachable goal: ask for the piece moved a little
                goal = piece + np.array([0.03, 0.0, 0.0], np.float32)
            try:
                approach = skill.approach_pose(piece, goal, scene=piece)  # type: ignore[call-arg]  # beyond the contract
            except TypeError:  # the two-argument contract signature
                approach = skill.approach_pose(piece, goal)
            run(skill.controller(), approach, goal, self.contract_controller_steps, "heuristic controller")


class PlannerContract:
    """Contract tests for a registered planner, on the analytic problem with a known optimum."""

    planner_name: ClassVar[str]
    planner_overrides: ClassVar[dict[str, Any]] = {}

    def plugins(self) -> Plugins:
        return get_plugins()

    def make_planner(self) -> Planner:
        return configured(self.plugins().planners, self.planner_name, self.planner_overrides)

    def test_conforms(self) -> None:
        check_planner(self.make_planner(), name=self.planner_name)

    def test_records_seed_name_initial_and_goal(self) -> None:
        problem = analytic_problem(seed=7)
        plan = self.make_planner().plan(problem)
        check_plan(plan, problem)  # seed, initial and goal latents, numbers against the models
        assert plan.seed == 7, f"plan.seed is {plan.seed}, expected the problem's seed 7"
        assert plan.planner == self.planner_name, f"plan.planner is {plan.planner!r}, expected {self.planner_name!r}"

    def test_honours_given_skeleton(self) -> None:
        skeleton = ("move", "split", "flatten")  # cardinality-consistent but not the optimum
        problem = analytic_problem(skeleton=skeleton)
        plan = self.make_planner().plan(problem)
        assert plan.skills == skeleton, (
            f"plan skeleton {plan.skills} ignores the given skeleton {skeleton} (score {plan.score:.4f})")
        check_plan(plan, problem)

    def test_finds_optimal_skeleton_and_attention(self) -> None:
        problem = analytic_problem()
        plan = self.make_planner().plan(problem)
        check_plan(plan, problem)
        found = f"(score {plan.score:.4f}, final cost {plan.final_cost:.5f}, feasibility {[round(s.feasibility, 3) for s in plan.steps]})"
        assert plan.skills == OPTIMAL_SKELETON, f"expected {OPTIMAL_SKELETON}, got {plan.skills} {found}"
        split, move, flatten = plan.steps
        moved = split.state[move.inputs[0]]
        assert abs(moved[0] - 0.4) < 0.1, f"move must act on the size-0.4 piece (size {moved[0]:.3f}), acted on {moved}"
        assert flatten.inputs[0] == 0, (
            f"flatten must act on the piece just moved (entity 0: produced entities come first), acted on {flatten.inputs}")
        assert plan.final_cost < 0.01, f"final cost {plan.final_cost:.5f}, expected < 0.01 {found}"
        assert plan.score > 0.5, f"score {plan.score:.4f}, expected > 0.5 {found}"


class TaskContract:
    """Contract tests for a registered task: its class, one instance and its scoring.

    ``task_overrides`` sets task config fields (e.g. ``{"n_particles": 2000}`` to generate faster);
    ``seed`` is the instance checked.
    """

    task_name: ClassVar[str]
    task_overrides: ClassVar[dict[str, Any]] = {}
    seed: ClassVar[int] = 1000

    def plugins(self) -> Plugins:
        return get_plugins()

    def make_task(self) -> Task:
        registry = self.plugins().tasks
        cfg = registry.default_config(self.task_name)
        for key, value in self.task_overrides.items():
            assert hasattr(cfg, key), f"task '{self.task_name}' config has no field '{key}'"
            setattr(cfg, key, value)
        return registry.create(self.task_name, cfg)

    def test_registered_class_is_a_task(self) -> None:
        cls = self.plugins().tasks.load(self.task_name)  # checks the pasta.core.Task base and the name
        assert issubclass(cls, Task) and cls.name == self.task_name, f"{cls} (name {cls.name!r})"

    def test_instance_conforms(self) -> None:
        check_task(self.make_task(), skills=self.plugins().skills, seed=self.seed)
