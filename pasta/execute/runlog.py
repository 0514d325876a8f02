"""Writes a plan's execution into a :class:`pasta.io.RunLogger` (the topics of docs/logging.md)."""

from __future__ import annotations

import io
from collections.abc import Mapping
from dataclasses import asdict
from typing import TYPE_CHECKING, Any

import numpy as np

from pasta.core.plan import Plan, PlanStep
from pasta.core.skill import Skill

if TYPE_CHECKING:
    from pasta.execute.executor import ExecutionResult, StepInfo

__all__ = ["ExecutionLog", "tool_primitives"]


def _tool_rgba(color: str) -> tuple[float, float, float, float]:
    """RGBA of a ToolSpec colour name (``"tab:red"``); the viewer's default grey for ``""``."""
    from pasta.io.schemas import DEFAULT_TOOL_COLOR

    if not color:
        return DEFAULT_TOOL_COLOR
    from matplotlib.colors import to_rgba

    r, g, b, a = to_rgba(color)
    return float(r), float(g), float(b), float(a)


def tool_primitives(sim: Any, poses: dict[str, np.ndarray] | None = None, apertures: dict[str, float] | None = None,
                    rgba: Mapping[str, tuple[float, ...]] | None = None) -> list[Any]:
    """Every tool of ``sim`` as :class:`pasta.io.ToolPrimitive` s (shapes from its ToolSpec, in its colour),
    at its current pose and aperture, or at ``poses`` / ``apertures`` (tool -> (7,) pose / aperture) where
    they name it. ``rgba``: tool -> colour, converted once by the caller (default: from each ToolSpec)."""
    from pasta.io import ToolPrimitive
    from pasta.sim.tools import tool_shapes

    prims = []
    for name in sim.tool_names:  # every tool of the simulator, drawn from its ToolSpec's primitives
        spec = sim.tool_spec(name)
        pose = (poses or {}).get(name)
        pose = sim.tool_pose(name) if pose is None else np.asarray(pose, np.float32)
        aperture = (apertures or {}).get(name)
        aperture = sim.tool_aperture(name) if aperture is None else aperture
        colour = rgba[name] if rgba and name in rgba else _tool_rgba(spec.color)
        for ent, kind, size, centre, quat in tool_shapes(spec, pose, aperture):
            prims.append(ToolPrimitive(ent, kind, size, centre, quat, colour))
    return prims


class ExecutionLog:
    """Writes an execution into a RunLogger (topics of docs/logging.md): the dough and the tools after every
    env step, every action and teleport (so ``pasta replay --verify`` can re-simulate the run), the plan,
    and one line per step start, retry, skip and end."""

    def __init__(self, logger: Any, sim: Any) -> None:
        self.log, self.sim = logger, sim
        self.env_dt = sim.cfg.dt * sim.cfg.substeps
        # the simulator's tool set is fixed: convert each ToolSpec colour once, not on every logged step
        self.tool_rgba = {name: _tool_rgba(sim.tool_spec(name).color) for name in sim.tool_names}

    def t(self, step: int) -> int:
        from pasta.io import step_time_ns

        return step_time_ns(step, self.env_dt)

    def start(self, obs: Any, goal: np.ndarray, plan: Plan) -> None:
        buf = io.BytesIO()
        self.sim.get_state().save(buf)
        self.log.attach("initial_state.npz", buf.getvalue(), "application/x-npz", t_ns=self.t(self.sim.step_count))
        self.log.attach_json("sim_config.json", asdict(self.sim.cfg))
        t = self.t(self.sim.step_count)
        self.log.point_cloud("/goal", t, goal)
        self.log.point_cloud("/dough", t, obs.dough)
        self.tools(t)
        self.plan(plan)
        self.log.flush()  # a killed run keeps its plan and initial state (fixed flush points: same bytes every run)

    def plan(self, plan: Plan) -> None:
        d = plan.to_dict(timings=True)
        d["cost"] = plan.final_cost
        for s in d["steps"]:
            s["outputs"] = len(s["subgoal"])
        self.log.plan(self.t(self.sim.step_count), d)

    def tools(self, t: int, override: dict[str, np.ndarray] | None = None) -> None:
        """Log every tool at its current pose (``override``: tool -> (7,) pose to show instead)."""
        self.log.tools("/tools", t, tool_primitives(self.sim, override, rgba=self.tool_rgba))

    def step_start(self, h: int, obs: Any, labels: np.ndarray, subgoal: list[np.ndarray], step: PlanStep,
                   attended: tuple[int, ...]) -> None:
        t = self.t(self.sim.step_count)
        self.log.entities("/entities", t, [obs.dough[labels == e] for e in range(int(labels.max()) + 1)])
        self.log.entities("/plan/subgoals", t, subgoal)
        self.log.message(t, "info", f"step {h}: {step.skill} on planned entities {list(step.inputs)} "
                                    f"-> observed entities {list(attended)}")

    def retry(self, h: int, skill: str, attempt: int, why: str) -> None:
        self.log.message(self.t(self.sim.step_count), "warning", f"step {h}: {skill} visibly failed ({why}); attempt {attempt}")

    def note(self, level: str, text: str) -> None:
        """A line on the run's log channel at the current simulation time."""
        self.log.message(self.t(self.sim.step_count), level, text)

    def skill_run(self, start: int, skill: Skill, res: Any, idle: int) -> None:
        tool, traj = skill.tool, res.trajectory
        s = start
        self.log.set_tool_pose(self.t(s), s, tool, list(res.approach.position), yaw=float(res.approach.yaw))
        for i, action in enumerate(traj.action):
            self.log.action(self.t(s + 1), s, tool, np.asarray(action, np.float32))
            s += 1
            self.log.point_cloud("/dough", self.t(s), traj.dough[i + 1])
            self.tools(self.t(s), {tool: traj.tool_pose[i + 1]})
        from pasta.io import ACTIONS
        from pasta.io.schemas import ACTION_SCHEMA

        for _ in range(idle):  # run_skill's idle steps: sim.step() with no tool action
            self.log.json(ACTIONS, self.t(s + 1), {"step": s, "actions": {}}, schema=ACTION_SCHEMA)
            s += 1
        pose = skill.park_pose()
        self.log.set_tool_pose(self.t(s), s, tool, list(pose.position), yaw=float(pose.yaw))
        t = self.t(self.sim.step_count)
        self.log.point_cloud("/dough", t, self.sim.observe().dough)
        self.tools(t)

    def disturbance(self, disturbance: Any) -> None:
        """The disturbance: its arrays as an attachment that ``pasta replay --verify`` applies at its env step
        (an ``/actions`` message names it), and a line saying what changed."""
        from pasta.io import ACTIONS
        from pasta.io.schemas import ACTION_SCHEMA

        t = self.t(self.sim.step_count)
        name = f"disturbance_{disturbance.step}.npz"
        self.log.attach(name, disturbance.to_npz(), "application/x-npz", t_ns=t)
        self.log.json(ACTIONS, t, {"step": int(self.sim.step_count), "disturb": name}, schema=ACTION_SCHEMA)
        self.log.message(t, "warning", f"disturbance ({disturbance.kind}): {disturbance.description}")
        self.log.point_cloud("/dough", t, self.sim.observe().dough)
        self.tools(t)

    def decision(self, decision: dict[str, Any], plan: Plan | None) -> None:
        """The closed loop's verdict after a step (kept or re-planned, and why); a re-plan is logged on /plan."""
        t = self.t(self.sim.step_count)
        from pasta.io.schemas import DECISION_SCHEMA

        self.log.json("/loop", t, decision, schema=DECISION_SCHEMA)
        level = "info" if decision["decision"] == "kept" else "warning"
        extra = f" -> {' -> '.join(decision['new'])}" if decision["decision"] == "replanned" else ""
        self.log.message(t, level, f"closed loop after step {decision['after_step']}: {decision['decision']} "
                                   f"({decision['reason']}){extra}")
        if plan is not None:
            self.plan(plan)

    def step_end(self, info: StepInfo) -> None:
        self.log.step_result(self.t(self.sim.step_count), {**info.to_dict(), "score": info.normalized_improvement})
        self.log.flush()  # a killed run loses at most the step in progress

    def finish(self, result: ExecutionResult) -> None:
        t = self.t(self.sim.step_count)
        if result.diverged is None:
            buf = io.BytesIO()
            self.sim.get_state().save(buf)
            self.log.attach("final_state.npz", buf.getvalue(), "application/x-npz", t_ns=t)
        self.log.metrics(t, {"normalized_improvement": result.normalized_improvement, "emd_initial": result.emd_initial,
                             "emd_final": result.emd_final, "steps": len(result.steps),
                             "env_steps": int(sum(s.env_steps for s in result.steps)),
                             "diverged": result.diverged is not None,
                             "replans": sum(d["decision"] == "replanned" for d in result.decisions),
                             "disturbance": result.disturbance["kind"] if result.disturbance else None})
