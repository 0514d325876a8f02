"""Execute a plan in the simulator and score it.

For each plan step (reference: PASTA's ``execute``; docs/policies.md):

1. observe and decompose the dough (DBSCAN, ``perception.*``);
2. the step's goal pieces (:func:`pasta.execute.goals.step_goal`): its sub-goal latents decoded, and in
   ``execute.goal=observed`` mode corrected by what the task's goal shows exactly;
3. the step to run and its attended pieces (:func:`pasta.execute.schedule.next_step`): plan order, the
   planned input indices at a plan's first step, then the observed pieces nearest the planned centroids;
   tracked by particle identity through the step;
4. the step monitor (:class:`pasta.tasks.step.GoalMonitor`) decides whether the step starts, when it ends
   and whether it runs once more; every skip, stop and retry is logged with its reason;
5. the skill runs through :func:`pasta.tasks.step.run_skill` (approach pose, the learned policy or the
   heuristic controller, idle steps, park).

The score is the normalised improvement ``(EMD_0 - EMD_T) / EMD_0`` of the observed dough to the goal
cloud. With a :class:`pasta.io.RunLogger` the run is logged in the replay-verifiable format of
docs/logging.md (:class:`pasta.execute.runlog.ExecutionLog`).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from pasta.core.decompose import decompose_labels
from pasta.core.errors import InputError
from pasta.core.metrics import emd, normalized_improvement
from pasta.core.plan import Plan
from pasta.core.skill import Controller, Skill
from pasta.core.step import Stop
from pasta.config.run import ExecuteConfig, PerceptionConfig
from pasta.execute.goals import step_goal
from pasta.execute.loop import join_labels
from pasta.execute.runlog import ExecutionLog
from pasta.execute.schedule import attend, next_step

__all__ = ["ExecuteConfig", "ExecutionResult", "StepInfo", "StepSnapshot", "execute_plan", "step_monitor"]

@dataclass
class StepInfo:
    """What happened at one executed plan step.

    Attributes:
        ended: why the step ended (a :class:`~pasta.core.Stop` value; ``at_goal``: it was skipped).
        attempts: how many times its skill ran (0: skipped; 2: retried once).
        plan_step: index of the executed step in its plan (differs from ``step`` when the order changed).
        plan: which plan it belongs to (0: the first; ``k``: the closed loop's ``k``-th re-plan).
    """

    step: int
    skill: str
    inputs: tuple[int, ...]
    attended: tuple[int, ...]
    entities_observed: int
    piece_points: int
    env_steps: int
    ended: str
    attempts: int
    emd: float
    normalized_improvement: float
    wall_s: float
    plan_step: int = -1
    plan: int = 0

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["inputs"], d["attended"] = list(self.inputs), list(self.attended)
        return d

    def describe(self) -> str:
        """One line for the command line: skill, pieces, env steps, why it ended, improvement after it."""
        if self.plan:
            moved = f" (re-plan {self.plan}, step {self.plan_step + 1})"
        else:
            moved = f" (plan step {self.plan_step + 1})" if self.plan_step not in (-1, self.step) else ""
        tries = f", {self.attempts} attempts" if self.attempts > 1 else ""
        return (f"executed {self.step + 1}. {self.skill:<6}{moved} on observed pieces {list(self.attended)}: "
                f"{self.env_steps} steps ({Stop(self.ended).describe}{tries}), "
                f"improvement {self.normalized_improvement:.3f}")


@dataclass
class StepSnapshot:
    """What one executed step left behind, for pictures (``pasta run summary=``).

    Attributes:
        dough: ``(P, 3)`` float32 observed dough after the step.
        tools: every tool as :class:`pasta.io.ToolPrimitive` s where it was when the step's motion ended
            (before parking); empty when the step was skipped.
        tool: the tool the step drove.
        path: ``(T+1, 3)`` that tool's centre over the step's (last) run; ``(0, 3)`` when skipped.
    """

    dough: np.ndarray
    tools: list[Any] = field(default_factory=list)
    tool: str = ""
    path: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), np.float32))


@dataclass
class ExecutionResult:
    """The outcome of :func:`execute_plan`: the score, per-step info and the final observed dough ``(P, 3)``.

    ``snapshots`` has one :class:`StepSnapshot` per entry of ``steps``; ``start_tools`` and ``end_tools`` are
    the tools (:class:`pasta.io.ToolPrimitive`) before the first step and after the last. ``plans``: the plan
    and every re-plan of a closed loop; ``decisions``: the closed loop's verdict after each step (kept or
    re-planned, why, seconds); ``disturbance``: what the disturbance changed (``Disturbance.summary``, with
    ``applied``), or why it could not be applied (``applied`` false)."""

    normalized_improvement: float
    emd_initial: float
    emd_final: float
    steps: list[StepInfo]
    final_dough: np.ndarray
    diverged: str | None = None
    plans: list[Plan] = field(default_factory=list)
    snapshots: list[StepSnapshot] = field(default_factory=list)
    start_tools: list[Any] = field(default_factory=list)
    end_tools: list[Any] = field(default_factory=list)
    decisions: list[dict[str, Any]] = field(default_factory=list)
    disturbance: dict[str, Any] | None = None


def step_monitor(cfg: ExecuteConfig, perception: PerceptionConfig) -> Any:
    """The step monitor of an execution (:class:`pasta.tasks.step.GoalMonitor`) with ``cfg``'s settings; a
    watched step whose piece is within ``perception.unchanged_threshold`` of its goal is at its goal, unless
    its skill says how close is at its goal (:attr:`pasta.core.Skill.at_goal`)."""
    from pasta.tasks.step import GoalMonitor

    return GoalMonitor(rise=float(cfg.regress_rise), near=float(cfg.regress_near), overrun=int(cfg.overrun),
                       at_goal=float(perception.unchanged_threshold))


def _tools(sim: Any, poses: dict[str, np.ndarray] | None = None, apertures: dict[str, float] | None = None) -> list[Any]:
    """Every tool of ``sim`` as ToolPrimitives (at ``poses`` where given); none for a stand-in simulator
    without tool specs."""
    from pasta.execute.runlog import tool_primitives

    if not hasattr(sim, "tool_spec") or not hasattr(sim, "tool_names"):
        return []
    return tool_primitives(sim, poses, apertures)


def _controller(skill: Skill, kind: str) -> Controller:
    return skill.policy() if kind == "learned" else skill.controller()


def execute_plan(
    sim: Any,
    plan: Plan,
    *,
    skills: Mapping[str, Skill],
    encoder: Any,
    goal: np.ndarray,
    cfg: ExecuteConfig | None = None,
    perception: PerceptionConfig | None = None,
    emd_points: int = 500,
    emd_seed: int = 0,
    logger: Any = None,
    disturb: str = "",
    seed: int = 0,
    replan: Callable[[np.ndarray, Plan, set[int], np.ndarray], Plan] | None = None,
) -> ExecutionResult:
    """Execute ``plan`` in ``sim`` (a :class:`pasta.sim.Simulator` with the scene loaded) and score it.

    Args:
        skills: skill name -> skill (with a policy attached for ``controller="learned"``).
        encoder: the :class:`~pasta.core.Encoder` that decodes the sub-goal latents.
        goal: ``(G, 3)`` goal cloud of the task (the score's reference).
        cfg: execution settings; ``perception``: decomposition settings (the planner's).
        emd_points, emd_seed: the task's EMD sample (:class:`pasta.tasks.TaskConfig`).
        logger: a :class:`pasta.io.RunLogger` (or ``None``): the execution is logged into it.
        disturb: a disturbance (:data:`pasta.sim.disturb.DISTURBANCES`) applied after the first executed step,
            drawn from ``seed``; ``""``: none.
        replan: the closed loop (``execute.loop=closed``): ``(observed dough (P, 3), plan, executed plan steps,
            entity labels (P,)) -> new plan`` of the remaining steps, called after a step when the plan no longer
            fits the observation (:func:`pasta.execute.loop.plan_fit`); ``None``: open loop.

    Returns:
        :class:`ExecutionResult` with the final normalised improvement and per-step info. Scores use the
        simulator's true dough, not what a noisy camera (``disturb=noise``) shows the controllers.
    """
    from pasta.sim import SimulationDiverged
    from pasta.tasks.step import run_skill

    cfg = cfg or ExecuteConfig()
    perception = perception or PerceptionConfig()
    missing = sorted({s.skill for s in plan.steps} - set(skills))
    if missing:
        raise InputError(f"the plan uses skills {missing} that were not given to the executor")
    goal = np.asarray(goal, np.float32)
    log = ExecutionLog(logger, sim) if logger is not None else None
    obs = sim.observe()
    emd0 = emd(obs.dough, goal, n=emd_points, seed=emd_seed)
    if log:
        log.start(obs, goal, plan)
    scene_scope = getattr(encoder, "scope", "entity") == "scene"

    joined: list[np.ndarray] = []  # groups of particle ids the closed loop counts as one piece (loop.join_labels)

    def entity_labels(points: np.ndarray, index: np.ndarray | None = None) -> np.ndarray:
        """``(P,)`` entity of every point; Flat 3D (a scene-scope encoder) sees the whole dough as one. With the
        points' particle ids ``index``, the pieces of each joined group count as one."""
        if scene_scope:
            return np.zeros(len(points), np.int64)
        labels = decompose_labels(points, min_points=perception.min_points)
        return join_labels(points, labels, index, joined) if joined and index is not None else labels

    goal_labels = entity_labels(goal) if cfg.goal == "observed" else None  # entity label of every goal point
    monitor = step_monitor(cfg, perception)
    infos: list[StepInfo] = []
    snapshots: list[StepSnapshot] = []
    start_tools = _tools(sim)
    diverged = None
    executed: set[int] = set()  # plan steps already run
    plans: list[Plan] = [plan]
    decisions: list[dict[str, Any]] = []
    disturbance, missed = None, None
    aimed: dict[tuple[int, int], np.ndarray] = {}  # (plan step, output) -> where the controller aimed it
    view = sim  # what the controllers and the closed loop observe (a noisy camera after disturb=noise)
    h = 0
    steps_cap = plan.horizon + 2 * MAX_REPLANS  # re-plans may add a step each

    while len(executed) < plan.horizon and h < steps_cap:
        t0 = time.perf_counter()
        obs = view.observe()
        labels = entity_labels(obs.dough, obs.dough_index)

        def prepare(j: int, labels: np.ndarray = labels, dough: np.ndarray = obs.dough, plan: Plan = plan,
                    executed: set[int] = executed) -> tuple[tuple[int, ...], np.ndarray, list[np.ndarray]]:
            """Plan step ``j``: the attended observed entities, their point indices and the controller's goal."""
            step = plan.steps[j]
            before = plan.initial if j == 0 else plan.steps[j - 1].state
            attended = attend(labels, dough, step, before, encoder.z_dim, first=j == 0 and not executed)
            subgoal = step_goal(plan, j, encoder, skills=skills, num_points=perception.num_points, goal=goal,
                                goal_labels=goal_labels)
            return attended, np.flatnonzero(np.isin(labels, attended)), subgoal

        h_plan, attended, idx, subgoal = next_step(plan, executed, prepare, obs.dough, labels,
                                                   lambda name: float(getattr(skills[name], "sweep_half_width", 0.0)))
        step = plan.steps[h_plan]
        skill = skills[step.skill]
        goal_points = np.concatenate(subgoal, 0)
        aimed.update({(h_plan, j): np.asarray(piece, np.float64).mean(0) for j, piece in enumerate(subgoal)})
        if log:
            log.step_start(h, obs, labels, subgoal, step, attended)
        controller = _controller(skill, cfg.controller)
        watch = bool(getattr(controller, "watch", False))
        ended = monitor.should_run(obs.dough[idx], goal_points, keeps_count=len(subgoal) == len(attended),
                                   watch=watch, at_goal=getattr(skill, "at_goal", None)) if len(idx) else None
        if ended is Stop.AT_GOAL and skill.unfinished(obs.dough[idx], goal_points):
            ended = None  # close by the distance, but the skill's own measure says the step is still to do
        steps_run, attempts, res = 0, 0, None
        expected = int(labels.max()) + 1 - len(attended) + skill.spec.n_out  # pieces after a successful step
        tracked = obs.dough_index[idx]  # the attended particles, by identity
        while ended is None or attempts:  # skipped (at its goal), or run until done or out of retries
            if attempts:  # re-attend: the pieces that hold most of the tracked particles, as observed now
                seen = view.observe()
                now = entity_labels(seen.dough, seen.dough_index)
                if len(idx):
                    ids = np.unique(now[idx], return_counts=True)
                    keep = ids[0][ids[1] >= 0.1 * len(idx)]
                    idx = np.flatnonzero(np.isin(now, keep))
                controller = _controller(skill, cfg.controller)
            start_step = sim.step_count
            try:
                res = run_skill(view, skill, controller, idx, goal_points, monitor=monitor,
                                idle_steps=cfg.idle_steps, record=log is not None)
            except SimulationDiverged as exc:  # a diverged simulation ends the episode, scored as is
                diverged, ended = str(exc), Stop.DIVERGED
                break
            steps_run, ended, attempts = steps_run + res.steps, res.ended, attempts + 1
            if log:
                log.skill_run(start_step, skill, res, cfg.idle_steps)
            after = view.observe()
            pieces = int(entity_labels(after.dough, after.dough_index).max()) + 1
            if not monitor.should_retry(pieces, expected, ended):
                break
            why = ended.describe if ended is Stop.LIMIT else f"{pieces} pieces observed, {expected} expected"
            if attempts > cfg.retries:
                if log:
                    log.note("warning", f"step {h}: {step.skill} visibly failed ({why}); no retries left")
                break
            if log:
                log.retry(h, step.skill, attempts + 1, why)
        if attempts == 0 and ended is Stop.AT_GOAL and log:
            log.note("info", f"step {h}: {step.skill} {Stop.AT_GOAL.describe}")
        final = obs.dough if diverged else sim.observe().dough  # the true dough: scores never see camera noise
        e = emd(final, goal, n=emd_points, seed=emd_seed)
        info = StepInfo(h, step.skill, step.inputs, attended, int(labels.max()) + 1, len(idx), steps_run,
                        str(Stop(ended)), attempts, e, normalized_improvement(emd0, e), time.perf_counter() - t0, h_plan,
                        len(plans) - 1)
        infos.append(info)
        if res is not None:
            snapshots.append(StepSnapshot(np.array(final, np.float32), _tools(sim, res.end_poses, res.end_apertures),
                                          skill.tool, np.asarray(res.path, np.float32)))
        else:  # skipped, or diverged in its first run: nothing moved where it can be drawn
            snapshots.append(StepSnapshot(np.array(final, np.float32), [], skill.tool))
        if log:
            log.step_end(info)
        if diverged:
            break
        executed.add(h_plan)
        h += 1
        if disturb and h == 1:
            try:
                disturbance = _disturb(sim, disturb, tracked, entity_labels, seed)
            except InputError as exc:  # e.g. merge in a scene of one piece: said, and the run goes on
                missed = {"kind": disturb, "applied": False, "description": f"not applied: {exc}"}
                if log:
                    log.note("warning", f"disturbance ({disturb}) {missed['description']}")
            else:
                view = disturbance.apply_to(sim)
                if log:
                    log.disturbance(disturbance)
        if replan is not None and len(executed) < plan.horizon:
            plan, executed = _closed_loop(view, plan, executed, replan, entity_labels, encoder.z_dim, cfg, h,
                                          len(plans) - 1, decisions, log, aimed,
                                          lambda name: bool(getattr(skills[name], "keeps_position", False)), joined,
                                          obs.dough_index)
            if plan is not plans[-1]:
                plans.append(plan)
                aimed = {}
    last = infos[-1] if infos else None
    final_dough = obs.dough if diverged else sim.observe().dough
    emd_t = last.emd if last else emd0
    result = ExecutionResult(normalized_improvement(emd0, emd_t), emd0, emd_t, infos, final_dough, diverged, plans,
                             snapshots, start_tools, _tools(sim) if not diverged else [], decisions,
                             disturbance.summary() if disturbance is not None else missed)
    if log:
        log.finish(result)
    return result


MAX_REPLANS = 3  # a closed loop re-plans at most this many times per episode (each may add one step)


def _disturb(sim: Any, kind: str, tracked: np.ndarray, entity_labels: Callable[[np.ndarray], np.ndarray],
             seed: int) -> Any:
    """The seeded disturbance of ``kind`` after the first step: the pieces that hold its ``tracked`` particles
    are the ones it produced."""
    from pasta.sim.disturb import make_disturbance, particle_labels

    seen = sim.observe()
    x = sim.particles()
    pieces = particle_labels(x, seen.dough, entity_labels(seen.dough))
    produced = sorted(set(np.unique(pieces[tracked]).tolist())) if len(tracked) else []
    return make_disturbance(kind, x, pieces, produced, step=sim.step_count, observed=len(seen.dough), seed=seed)


def _closed_loop(view: Any, plan: Plan, executed: set[int],
                 replan: Callable[[np.ndarray, Plan, set[int], np.ndarray], Plan],
                 entity_labels: Callable[..., np.ndarray], z_dim: int, cfg: ExecuteConfig, h: int,
                 replans: int, decisions: list[dict[str, Any]], log: Any,
                 aimed: dict[tuple[int, int], np.ndarray], keeps_position: Callable[[str], bool],
                 joined: list[np.ndarray], known: np.ndarray) -> tuple[Plan, set[int]]:
    """After step ``h``: keep ``plan`` when it fits the observation, else re-plan its remaining steps; when no
    sequence can bring the observed pieces to the plan's count, join each extra piece of dough the plan knew
    (particle ids ``known`` at the step's start) to the piece it belongs to (appended to ``joined``) and test
    again. Appends the decision (kept / re-planned, why, seconds) to
    ``decisions`` and logs it (:mod:`pasta.execute.loop`)."""
    from pasta.core.errors import CardinalityError
    from pasta.execute.loop import extra_pieces, plan_fit, remaining_skills

    t0 = time.perf_counter()
    seen = view.observe()
    labels = entity_labels(seen.dough, seen.dough_index)
    fit = plan_fit(plan, executed, seen.dough, labels, z_dim, float(cfg.fit_distance), aimed, keeps_position)
    decision: dict[str, Any] = {"after_step": h - 1, "decision": "kept", "reason": fit.reason,
                                "distance_m": fit.distance if np.isfinite(fit.distance) else None,
                                "observed": fit.observed, "expected": fit.expected}
    new_plan, new_executed = plan, executed
    for _ in range(2):  # a re-plan; after joining extra pieces, the test and (if needed) a re-plan once more
        if fit.fits:
            break
        if replans >= MAX_REPLANS:
            decision["reason"] += f"; no re-plans left ({MAX_REPLANS} per episode)"
            break
        try:
            new_plan = replan(seen.dough, plan, executed, labels)
        except CardinalityError as exc:
            pairs = extra_pieces(plan, executed, seen.dough, labels, z_dim, aimed, index=seen.dough_index,
                                 known=known) if not decision.get("joined") else []
            if not pairs:
                decision["reason"] += f"; re-plan failed ({type(exc).__name__}: {exc})"
                break
            for extra, nearest in pairs:  # one group per pair, merged with any group it touches
                ids = seen.dough_index[np.isin(labels, [extra, nearest])]
                touching = [g for g in joined if np.isin(g, ids).any()]
                for g in touching:
                    joined.remove(g)
                joined.append(np.unique(np.concatenate([ids, *touching])))
            decision["joined"] = [[int(a), int(b)] for a, b in pairs]
            labels = entity_labels(seen.dough, seen.dough_index)
            fit = plan_fit(plan, executed, seen.dough, labels, z_dim, float(cfg.fit_distance), aimed, keeps_position)
            decision["reason"] += (f"; no skill sequence reaches the plan's count: observed pieces "
                                   f"{', '.join(f'{a} and {b}' for a, b in pairs)} count as one from now on; "
                                   f"then: {fit.reason}")
            continue
        except Exception as exc:  # noqa: BLE001 - a failed re-plan keeps the plan; the run goes on
            decision["reason"] += f"; re-plan failed ({type(exc).__name__}: {exc})"
            break
        new_executed = set()
        decision.update(decision="replanned", remaining=list(remaining_skills(plan, executed)),
                        new=[s.skill for s in new_plan.steps],
                        cost=float(new_plan.final_cost))
        break
    decision["seconds"] = round(time.perf_counter() - t0, 3)
    decisions.append(decision)
    if log:
        log.decision(decision, new_plan if new_plan is not plan else None)
    return new_plan, new_executed
