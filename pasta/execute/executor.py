"""Execute a plan in the simulator and score it.

For each plan step (reference: PASTA's ``execute``, our docs/policies.md):

1. observe and decompose the dough (DBSCAN, ``min_points`` 50);
2. decode the step's sub-goal latents with the encoder (``decode_points`` per entity) and concatenate
   them: that is the controller's goal;
3. pick the attended piece: at the first step of a plan the entities at the plan's input indices; at
   later steps, for each planned input entity, the observed entity whose centroid is nearest to the
   planned centroid ``t`` (each observed entity used once). The piece is tracked by particle identity
   through the step (the simulator observes a fixed particle subset, ``Observation.dough_index``);
4. optionally skip the step when the whole dough already matches the decoded planned state
   (Chamfer below ``skip_threshold``; the paper's ``exec_threshold``);
5. run the skill through :func:`pasta.tasks.executor.run_skill`: approach pose, the learned policy or
   the heuristic controller up to ``max_steps`` or done, ``idle_steps`` zero-action steps, park;
6. closed loop (optional): re-plan from the new observation for the remaining steps.

The score is the normalised improvement ``(EMD_0 - EMD_T) / EMD_0`` of the observed dough to the
goal cloud. With a :class:`pasta.io.RunLogger` the run is logged in the replay-verifiable format of
docs/logging.md (initial/final state, sim config, every teleport and env step on ``/actions``).
"""

from __future__ import annotations

import io
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from pasta.core.decompose import decompose_labels
from pasta.core.errors import CardinalityError, ConfigError, InputError
from pasta.core.metrics import chamfer, emd, normalized_improvement
from pasta.core.plan import Plan, PlanStep, kept_indices
from pasta.core.skill import Controller, Skill

__all__ = ["ExecuteConfig", "ExecutionResult", "StepInfo", "anchor_xz", "attend", "decode_entities", "equalise_density",
           "execute_plan", "goal_descendants", "match_goal_pieces", "step_dependencies", "step_goal", "sweep_risk"]


@dataclass
class ExecuteConfig:
    """Settings of plan execution (``execute.*`` on ``pasta run``).

    Attributes:
        controller: ``"heuristic"`` (the skill's point-cloud controller) or ``"learned"`` (its attached
            policy, ``pasta train policy``).
        max_steps: controller steps per skill at most (0: the skill's own ``max_steps``: cut 130, push
            80, roll 100 for the built-in skills).
        idle_steps: zero-action steps after each skill.
        min_points: DBSCAN clusters smaller than this are noise (50 at execution, as in the paper).
        decode_points: points per decoded sub-goal entity.
        skip_threshold: skip a step whose decoded planned state is already within this Chamfer
            distance of the dough (0 disables).
        closed_loop: re-plan after each executed step from the new observation (needs a re-planner).
        goal_pieces: a produced entity that no later step touches is part of the plan's final state, which
            the planner matched to the goal: give the controller that observed goal piece (matched by
            centroid) instead of the entity's decoding. Decodings blur thin pieces (a rolled sheet decodes
            about twice as thick), and the goal is known exactly.
        goal_mass: when every output of a step becomes goal pieces (through later steps that each take
            one entity, so keep its mass: cut, push, roll), resample the step's goal pieces to point
            counts proportional to those goal pieces' point counts, not to decoded volumes: the
            observation is a fixed particle subset, so counts are masses, and the cut controller reads
            its split from them.
        goal_anchor: aim an output that only steps of skills with :attr:`~pasta.core.Skill.keeps_position`
            follow (a piece pushed and then rolled) at its goal piece's place: its decoding is moved so
            its horizontal centroid is the goal piece's.
        retries: run a step again (from the new observation, same sub-goal) when it visibly failed: the
            controller hit its step limit without reporting done, or fewer pieces are observed than the
            skill produces (a cut whose bottom layer still joins the halves). 0 disables.
        reorder: run a later plan step first when the next one would sweep its piece (and its tool's
            band, :attr:`~pasta.core.Skill.sweep_half_width`) through another observed piece and the
            later step does not depend on it (it consumes nothing the skipped steps produce); see
            :func:`sweep_risk`. The plan's latent states do not change, only the order.
        regress_stop: which controllers a :class:`~pasta.tasks.executor.RegressionStop` watches:
            ``"learned"`` (default: a learned policy's done head may stay low while it pushes past its
            goal, docs/policies.md), ``"all"`` or ``"off"``. It ends a step once the attended piece,
            having come at least halfway to the step's goal (Chamfer), moves away from it again by more
            than ``regress_rise`` of its best distance for 3 env steps.
        regress_progress: the watch starts once the step's best distance is below this fraction of its
            starting one (default 0.5, "halfway"; 1: as soon as it comes any closer).
        regress_near: a watched step whose attended piece starts within this Chamfer distance of the
            step's goal is at its goal already and is stopped as soon as it moves away (a learned roll of
            a piece the plan rolled once before spreads it on; 0 disables). 0.001: on the crs_twice validation
            configs such second rolls started 0.0002-0.0009 from their goal and first rolls 0.0009-0.0033
            (docs/policies.md, "crs_twice with learned policies").
        overrun: a watched learned policy that reaches its own step cap (``max_steps`` of its checkpoint,
            chosen on single-skill configs) runs on for at most this many env steps while each of them brings
            the attended piece closer to the step's goal than before (0 disables; see
            :class:`~pasta.tasks.executor.RegressionStop`).
        skip_near: a watched step that takes as many pieces as it produces, whose attended pieces already
            lie within ``regress_near`` of the step's goal, is skipped instead of started (a per-piece form
            of ``skip_threshold``: a learned roll of a piece that is flat already only spreads it on). A
            cut is never skipped: to Chamfer a dough and its two halves a few millimetres apart are close.
        unchanged_threshold: an observed entity within this Chamfer distance of a goal entity already is
            that goal piece: the planner never attends it and matches it to that piece in the set cost
            (:func:`pasta.core.matching.unchanged_pairs`, ``PlanningProblem.fixed``; 0 disables).
        emd_points: points per cloud of the EMD score; ``emd_seed`` its sampling seed.
        log_every: log the dough cloud every this many env steps (actions are always logged).
    """

    controller: str = "heuristic"
    max_steps: int = 0
    idle_steps: int = 10
    min_points: int = 50
    decode_points: int = 1000
    skip_threshold: float = 0.0
    closed_loop: bool = False
    goal_pieces: bool = True
    goal_mass: bool = True
    goal_anchor: bool = True
    retries: int = 1
    reorder: bool = True
    regress_stop: str = "learned"
    regress_rise: float = 0.5
    regress_progress: float = 0.5
    regress_near: float = 0.001
    overrun: int = 40
    skip_near: bool = True
    unchanged_threshold: float = 5e-4
    emd_points: int = 500
    emd_seed: int = 0
    log_every: int = 1

    def __post_init__(self) -> None:
        if self.controller not in ("learned", "heuristic"):
            raise ConfigError(f"execute.controller must be 'learned' or 'heuristic', got {self.controller!r}")
        if self.max_steps < 0 or self.idle_steps < 0 or self.min_points < 1 or self.decode_points < 1:
            raise ConfigError("execute: min_points, decode_points must be >= 1, max_steps and idle_steps >= 0")
        if str(self.regress_stop).lower() in ("false", "off", "no"):  # YAML 1.1 reads a bare `off` as false
            self.regress_stop = "off"
        if self.regress_stop not in ("learned", "all", "off"):
            raise ConfigError(f"execute.regress_stop must be 'learned', 'all' or 'off', got {self.regress_stop!r}")
        if not self.regress_rise > 0:
            raise ConfigError(f"execute.regress_rise must be a number > 0, got {self.regress_rise!r}")
        if not 0 < self.regress_progress <= 1:  # also NaN
            raise ConfigError(f"execute.regress_progress must be a number in (0, 1], got {self.regress_progress!r}")
        if not self.regress_near >= 0:  # also NaN
            raise ConfigError(f"execute.regress_near must be a number >= 0, got {self.regress_near!r}")
        if int(self.overrun) < 0:
            raise ConfigError(f"execute.overrun must be an integer >= 0 (env steps), got {self.overrun!r}")
        if not self.unchanged_threshold >= 0:  # also NaN
            raise ConfigError(f"execute.unchanged_threshold must be >= 0, got {self.unchanged_threshold}")

    def regression_stop(self) -> Any:
        """The :class:`~pasta.tasks.executor.RegressionStop` that watches this config's controller, or ``None``."""
        from pasta.tasks.executor import RegressionStop

        if self.regress_stop == "all" or self.regress_stop == self.controller:
            return RegressionStop(rise=float(self.regress_rise), progress=float(self.regress_progress),
                                  near=float(self.regress_near), overrun=int(self.overrun))
        return None


@dataclass
class StepInfo:
    """What happened at one executed plan step."""

    step: int
    skill: str
    inputs: tuple[int, ...]
    attended: tuple[int, ...]
    entities_observed: int
    piece_points: int
    env_steps: int
    done: bool
    skipped: bool
    emd: float
    normalized_improvement: float
    wall_s: float
    plan_step: int = -1  # index of the executed step in its plan (differs from ``step`` when reordered)
    stopped: bool = False  # a RegressionStop ended (one of) its controller run(s)

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["inputs"], d["attended"] = list(self.inputs), list(self.attended)
        return d


@dataclass
class ExecutionResult:
    """The outcome of :func:`execute_plan`: the score, per-step info and the final observed dough ``(P, 3)``."""

    normalized_improvement: float
    emd_initial: float
    emd_final: float
    steps: list[StepInfo]
    final_dough: np.ndarray
    plans: list[Plan] = field(default_factory=list)
    diverged: str | None = None
    #: closed loop: re-plans that found no plan for the observed pieces (the plan before them ran on)
    replan_errors: list[str] = field(default_factory=list)


def decode_entities(encoder: Any, latents: Sequence[Sequence[float]], num_points: int) -> list[np.ndarray]:
    """Decode ``(K, D)`` latents with ``encoder`` into ``K`` clouds ``(num_points, 3)`` float32.

    A decoder gives every entity the same point count; :func:`equalise_density` restores an
    observation's density (the cut controller reads the volume split from the goal's point fractions,
    and the policies were trained on observed goals).
    """
    import torch

    if len(latents) == 0:
        return []
    with torch.no_grad():
        out = encoder.decode(torch.as_tensor(np.asarray(latents, np.float32)), num_points)
    out = out.detach().cpu().numpy() if hasattr(out, "detach") else np.asarray(out)
    return [np.asarray(c, np.float32) for c in out]


def equalise_density(clouds: Sequence[np.ndarray], num_points: int, *, voxel: float = 1.0 / 64,
                     masses: Sequence[float] | None = None) -> list[np.ndarray]:
    """Resample ``clouds`` (each ``(N_i, 3)``) to point counts proportional to their volumes.

    The largest (by occupied ``voxel`` cells, or by ``masses`` when given: one per cloud, e.g. the point
    counts of the goal pieces they become) gets ``num_points`` points; points are taken in order (a
    decoder's Sobol template stays well spread) and repeated cyclically when a cloud has too few.
    """
    if len(clouds) < 2:
        return [np.asarray(c, np.float32) for c in clouds]
    if masses is not None:
        if len(masses) != len(clouds) or min(masses) <= 0:
            raise InputError(f"equalise_density: need one positive mass per cloud, got {list(masses)} for {len(clouds)} clouds")
        volumes = np.asarray(masses, np.float64)
    else:
        volumes = np.array([len(np.unique(np.floor(np.asarray(c) / voxel).astype(np.int64), axis=0)) for c in clouds],
                           np.float64)
    counts = np.maximum(1, np.round(num_points * volumes / volumes.max())).astype(int)
    return [np.asarray(c, np.float32)[np.arange(n) % len(c)] for c, n in zip(clouds, counts)]


def _origins(plan: Plan) -> list[list[tuple[int, int]]]:
    """The set bookkeeping of ``plan``: for the set before each step and the final set, every entity as
    ``(step that produced it, output index)`` (``-1`` and its index for an initial entity)."""
    ids: list[tuple[int, int]] = [(-1, i) for i in range(len(plan.initial))]
    out = [ids]
    for k, step in enumerate(plan.steps):
        ids = [(k, j) for j in range(len(step.subgoal))] + [ids[i] for i in kept_indices(len(ids), step.inputs)]
        out.append(ids)
    return out


def goal_descendants(plan: Plan, h: int) -> dict[int, tuple[tuple[int, ...], tuple[str, ...]]]:
    """``{output j of step h: (indices in the final set it becomes, skills of the later steps on the way)}``.

    Follows what output ``j`` becomes through the later steps that consume it or its parts, as long as
    each of them takes a single entity (a cut splits it, a push or roll moves or shapes it; none adds
    another entity's dough). Empty skills: ``j`` itself persists. Outputs that a later many-entity step
    consumes (a merge) are left out.
    """
    before = _origins(plan)
    final = {ent: pos for pos, ent in enumerate(before[-1])}
    out: dict[int, tuple[tuple[int, ...], tuple[str, ...]]] = {}
    for j in range(len(plan.steps[h].subgoal)):
        parts, chain = {(h, j)}, []
        for k in range(h + 1, len(plan.steps)):
            step = plan.steps[k]
            consumed = {before[k][i] for i in step.inputs} & parts
            if not consumed:
                continue
            if len(step.inputs) != 1:
                break
            parts = (parts - consumed) | {(k, m) for m in range(len(step.subgoal))}
            chain.append(step.skill)
        else:
            out[j] = (tuple(sorted(final[e] for e in parts)), tuple(chain))
    return out


def step_dependencies(plan: Plan) -> list[set[int]]:
    """Per plan step, the earlier steps whose produced entities it consumes (directly)."""
    before = _origins(plan)
    return [{before[h][i][0] for i in step.inputs if before[h][i][0] >= 0} for h, step in enumerate(plan.steps)]


def sweep_risk(piece: np.ndarray, target: np.ndarray, others: np.ndarray, *, half_width: float = 0.0,
               margin: float = 0.02) -> int:
    """Points of ``others (O, 3)`` in the band a push of ``piece (P, 3)`` to centroid ``target (2,)`` (x, z)
    sweeps: ahead of the piece's start, up to its front at the target, and within the piece's (or the
    tool's ``half_width``, whichever is wider) lateral half extent plus ``margin`` of the line."""
    if len(others) == 0 or len(piece) == 0:
        return 0
    xz = np.asarray(piece, np.float64)[:, [0, 2]]
    c = xz.mean(0)
    d = np.asarray(target, np.float64) - c
    length = float(np.linalg.norm(d))
    if length < 1e-3:
        return 0
    u = d / length
    n = np.array([-u[1], u[0]])
    rel = xz - c
    front = float((rel @ u).max())
    width = max(float(np.abs(rel @ n).max()), half_width) + margin
    q = np.asarray(others, np.float64)[:, [0, 2]] - c
    s, lat = q @ u, np.abs(q @ n)
    return int(np.count_nonzero((s > 0) & (s < length + front + margin) & (lat < width)))


def anchor_xz(cloud: np.ndarray, piece: np.ndarray) -> np.ndarray:
    """``cloud (N, 3)`` moved horizontally so that its x, z centroid is that of ``piece (M, 3)``."""
    cloud = np.asarray(cloud, np.float32).copy()
    shift = np.asarray(piece, np.float64)[:, [0, 2]].mean(0) - cloud[:, [0, 2]].astype(np.float64).mean(0)
    cloud[:, [0, 2]] += shift.astype(np.float32)
    return cloud


def match_goal_pieces(final: Sequence[Sequence[float]], goal: np.ndarray, labels: np.ndarray, z_dim: int) -> dict[int, np.ndarray]:
    """``{final-set index: goal piece (N, 3)}``: planned final entities matched to observed goal pieces by centroid."""
    from scipy.optimize import linear_sum_assignment

    k = int(labels.max()) + 1 if len(labels) else 0
    if k == 0 or len(final) == 0:
        return {}
    pieces = [goal[labels == e] for e in range(k)]
    planned = np.asarray(final, np.float64)[:, z_dim : z_dim + 3]
    dist = np.linalg.norm(planned[:, None, :] - np.stack([p.mean(0) for p in pieces])[None], axis=-1)
    rows, cols = linear_sum_assignment(dist)
    return {int(r): pieces[c] for r, c in zip(rows, cols)}


def attend(labels: np.ndarray, points: np.ndarray, step: PlanStep, planned_before: Sequence[Sequence[float]],
           z_dim: int, first: bool) -> tuple[int, ...]:
    """Observed entity ids the step acts on.

    Args:
        labels: ``(P,)`` entity id of every observed point.
        points: ``(P, 3)`` observed dough.
        step: the plan step (its ``inputs`` index ``planned_before``).
        planned_before: ``(K, D)`` planned latent set before the step.
        z_dim: shape-code size ``Z``; the centroid is ``u[Z:Z+3]``.
        first: the first step of a plan: take the observed entities at the input indices when they exist.
    """
    k = int(labels.max()) + 1
    if first and all(i < k for i in step.inputs):
        return tuple(int(i) for i in step.inputs)
    centroids = np.stack([points[labels == e].mean(0) for e in range(k)])
    chosen: list[int] = []
    for i in step.inputs:
        t = np.asarray(planned_before[i], np.float64)[z_dim : z_dim + 3]
        d = np.linalg.norm(centroids - t, axis=1)
        d[chosen] = np.inf
        if not np.isfinite(d).any():
            raise InputError(f"step '{step.skill}' needs {len(step.inputs)} pieces but only {k} are observed")
        chosen.append(int(np.argmin(d)))
    return tuple(chosen)


def step_goal(plan: Plan, j: int, encoder: Any, cfg: ExecuteConfig, *, skills: Mapping[str, Skill],
              goal: np.ndarray | None = None, goal_labels: np.ndarray | None = None) -> list[np.ndarray]:
    """The controller's goal pieces for step ``j`` of ``plan``: one cloud ``(N_k, 3)`` per produced entity.

    Each sub-goal latent is decoded; with the task's ``goal (G, 3)`` and its entity labels ``(G,)``
    (``cfg.goal_pieces``), the plan's final entities are matched to the goal pieces and an output that
    persists takes its goal piece, one that only :attr:`~pasta.core.Skill.keeps_position` steps follow is
    moved onto its goal piece's place (``cfg.goal_anchor``), and when every output becomes goal pieces
    (:func:`goal_descendants`) the point counts follow those pieces' masses (``cfg.goal_mass``);
    otherwise decoded volumes (:func:`equalise_density`).
    """
    subgoal = decode_entities(encoder, plan.steps[j].subgoal, cfg.decode_points)
    masses: dict[int, float] = {}  # output -> point count of the goal piece it becomes
    if goal is not None and goal_labels is not None:
        matched = match_goal_pieces(plan.steps[-1].state, goal, goal_labels, encoder.z_dim)
        for k, (positions, chain) in goal_descendants(plan, j).items():
            if not all(pos in matched for pos in positions):
                continue
            masses[k] = float(sum(len(matched[pos]) for pos in positions))  # cuts, pushes and rolls keep mass
            if not chain:
                subgoal[k] = matched[positions[0]]
            elif (cfg.goal_anchor and len(positions) == 1
                  and all(getattr(skills[s], "keeps_position", False) for s in chain)):
                subgoal[k] = anchor_xz(subgoal[k], matched[positions[0]])
    exact = cfg.goal_mass and len(masses) == len(subgoal)
    return equalise_density(subgoal, cfg.decode_points, masses=[masses[k] for k in range(len(subgoal))] if exact else None)


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
    replan: Callable[[np.ndarray, int], Plan] | None = None,
    logger: Any = None,
) -> ExecutionResult:
    """Execute ``plan`` in ``sim`` (a :class:`pasta.sim.Simulator` with the scene loaded) and score it.

    Args:
        skills: skill name -> skill (with a policy attached for ``controller="learned"``).
        encoder: the :class:`~pasta.core.Encoder` that decodes the sub-goal latents.
        goal: ``(G, 3)`` goal cloud of the task (the score's reference).
        cfg: execution settings.
        replan: ``(observed dough (P, 3), steps left) -> Plan``, used when ``cfg.closed_loop``.
        logger: a :class:`pasta.io.RunLogger` (or ``None``): the execution is logged into it.

    Returns:
        :class:`ExecutionResult` with the final normalised improvement and per-step info.
    """
    from pasta.tasks.executor import run_skill

    cfg = cfg or ExecuteConfig()
    if cfg.closed_loop and replan is None:
        raise ConfigError("execute.closed_loop needs a re-planner (pasta run provides one)")
    missing = sorted({s.skill for s in plan.steps} - set(skills))
    if missing:
        raise InputError(f"the plan uses skills {missing} that were not given to the executor")
    goal = np.asarray(goal, np.float32)
    log = _Log(logger, sim, cfg.log_every) if logger is not None else None
    obs = sim.observe()
    emd0 = emd(obs.dough, goal, n=cfg.emd_points, seed=cfg.emd_seed)
    if log:
        log.start(obs, goal, plan)
    horizon = plan.horizon
    plans, current = [plan], plan
    scene_scope = getattr(encoder, "scope", "entity") == "scene"

    def entity_labels(points: np.ndarray) -> np.ndarray:
        """``(P,)`` entity of every point; Flat 3D (a scene-scope encoder) sees the whole dough as one."""
        return np.zeros(len(points), np.int64) if scene_scope else decompose_labels(points, min_points=cfg.min_points)

    goal_labels = entity_labels(goal) if cfg.goal_pieces else None  # entity label of every goal point
    infos: list[StepInfo] = []
    replan_errors: list[str] = []
    diverged = None
    executed: set[int] = set()  # plan steps of ``current`` already run

    def prepare(j: int, obs: Any, labels: np.ndarray) -> tuple[tuple[int, ...], np.ndarray, list[np.ndarray]]:
        """Plan step ``j``: the attended observed entities, their point indices and the controller's goal pieces."""
        step = current.steps[j]
        before = current.initial if j == 0 else current.steps[j - 1].state
        attended = attend(labels, obs.dough, step, before, encoder.z_dim, first=j == 0 and not executed)
        subgoal = step_goal(current, j, encoder, cfg, skills=skills, goal=goal, goal_labels=goal_labels)
        return attended, np.flatnonzero(np.isin(labels, attended)), subgoal

    def pick(obs: Any, labels: np.ndarray) -> tuple[int, tuple[int, ...], np.ndarray, list[np.ndarray]]:
        """The next plan step to run: plan order, unless it would sweep through another piece and a later
        independent step would not (``cfg.reorder``)."""
        deps = step_dependencies(current)
        ready = [j for j in range(len(current.steps)) if j not in executed and deps[j] <= executed]
        choice = None
        for j in ready:
            attended, idx, subgoal = prepare(j, obs, labels)
            if not cfg.reorder or len(ready) == 1:
                return j, attended, idx, subgoal
            if choice is None:
                choice = (j, attended, idx, subgoal)
            others = obs.dough[~np.isin(labels, attended)]
            target = np.concatenate(subgoal, 0)[:, [0, 2]].mean(0)
            width = float(getattr(skills[current.steps[j].skill], "sweep_half_width", 0.0))
            if sweep_risk(obs.dough[idx], target, others, half_width=width) == 0:
                return j, attended, idx, subgoal
        assert choice is not None
        return choice

    for h in range(horizon):
        t0 = time.perf_counter()
        obs = sim.observe()
        labels = entity_labels(obs.dough)
        h_plan, attended, idx, subgoal = pick(obs, labels)
        step = current.steps[h_plan]
        skill = skills[step.skill]
        goal_points = np.concatenate(subgoal, 0)
        skipped = False
        if cfg.skip_threshold > 0:
            planned = np.concatenate(decode_entities(encoder, step.state, cfg.decode_points), 0)
            skipped = float(chamfer(obs.dough, planned)) < cfg.skip_threshold
        watch = cfg.regression_stop()
        if cfg.skip_near and watch is not None and len(idx) and len(subgoal) == len(attended):
            # a step that changes the piece count (a cut) is never done before it runs: to Chamfer, a dough
            # and its two halves a few millimetres apart are close
            skipped = skipped or watch.at_goal(obs.dough[idx], goal_points)
        if log:
            log.step_start(h, obs, labels, subgoal, step, attended)
        steps_run, done, stopped = 0, False, False
        expected = int(labels.max()) + 1 - len(attended) + skill.spec.n_out  # pieces after a successful step
        attempts = 0
        while not skipped and diverged is None and attempts <= cfg.retries:
            if attempts:  # re-attend: the pieces that hold most of the tracked particles, as observed now
                now = entity_labels(sim.observe().dough)
                if len(idx):
                    ids = np.unique(now[idx], return_counts=True)
                    keep = ids[0][ids[1] >= 0.1 * len(idx)]
                    idx = np.flatnonzero(np.isin(now, keep))
                if log:
                    log.retry(h, step.skill, attempts + 1)
            controller = _controller(skill, cfg.controller)
            start_step = sim.step_count
            try:
                res = run_skill(sim, skill, controller, idx, goal_points, max_steps=cfg.max_steps or None,
                                idle_steps=cfg.idle_steps, record=log is not None, stop=watch)
                steps_run, done, stopped = steps_run + res.steps, res.done, stopped or res.stopped
                if log:
                    log.skill_run(start_step, skill, res, cfg.idle_steps)
            except Exception as exc:  # noqa: BLE001 - a diverged simulation ends the episode, scored as is
                from pasta.sim import SimulationDiverged

                if not isinstance(exc, SimulationDiverged):
                    raise
                diverged = str(exc)
                break
            attempts += 1
            pieces = int(entity_labels(sim.observe().dough).max()) + 1
            if done and pieces >= expected:
                break
        final = obs.dough if diverged else sim.observe().dough
        e = emd(final, goal, n=cfg.emd_points, seed=cfg.emd_seed)
        info = StepInfo(h, step.skill, step.inputs, attended, int(labels.max()) + 1, len(idx), steps_run, done,
                        skipped, e, normalized_improvement(emd0, e), time.perf_counter() - t0, h_plan, stopped)
        infos.append(info)
        if log:
            log.step_end(info)
        if diverged:
            break
        executed.add(h_plan)
        if cfg.closed_loop and h + 1 < horizon:
            try:
                fresh = replan(sim.observe().dough, horizon - h - 1)
            except CardinalityError as exc:
                # the observed pieces no longer fit the rest of the given skeleton (two pieces touch, or a
                # cut left one): no re-plan exists, so the rest of the current plan runs open loop
                replan_errors.append(f"after step {h}: {exc}")
                continue
            current, executed = fresh, set()
            plans.append(current)
            if log:
                log.plan(current)
    final = infos[-1] if infos else None
    final_dough = obs.dough if diverged else sim.observe().dough
    emd_t = final.emd if final else emd0
    result = ExecutionResult(normalized_improvement(emd0, emd_t), emd0, emd_t, infos, final_dough, plans, diverged,
                             replan_errors)
    if log:
        log.finish(result)
    return result


def _tool_rgba(color: str) -> tuple[float, float, float, float]:
    """RGBA of a ToolSpec colour name (``"tab:red"``); the viewer's default grey for ``""``."""
    from pasta.io.schemas import DEFAULT_TOOL_COLOR

    if not color:
        return tuple(DEFAULT_TOOL_COLOR)
    from matplotlib.colors import to_rgba

    return tuple(float(v) for v in to_rgba(color))


class _Log:
    """Writes an execution into a RunLogger (topics of docs/logging.md)."""

    def __init__(self, logger: Any, sim: Any, every: int = 1) -> None:
        self.log, self.sim, self.every = logger, sim, max(1, every)
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
        from pasta.io import ToolPrimitive
        from pasta.sim.tools import tool_shapes

        prims = []
        for name in self.sim.tool_names:  # every tool of the simulator, drawn from its ToolSpec's primitives
            pose = (override or {}).get(name)
            pose = self.sim.tool_pose(name) if pose is None else np.asarray(pose, np.float32)
            for ent, kind, size, centre, quat in tool_shapes(self.sim.tool_spec(name), pose, self.sim.tool_aperture(name)):
                prims.append(ToolPrimitive(ent, kind, size, centre, quat, self.tool_rgba[name]))
        self.log.tools("/tools", t, prims)

    def step_start(self, h: int, obs: Any, labels: np.ndarray, subgoal: list[np.ndarray], step: PlanStep,
                   attended: tuple[int, ...]) -> None:
        t = self.t(self.sim.step_count)
        self.log.entities("/entities", t, [obs.dough[labels == e] for e in range(int(labels.max()) + 1)])
        self.log.entities("/plan/subgoals", t, subgoal)
        self.log.message(t, "info", f"step {h}: {step.skill} on planned entities {list(step.inputs)} "
                                    f"-> observed entities {list(attended)}")

    def retry(self, h: int, skill: str, attempt: int) -> None:
        self.log.message(self.t(self.sim.step_count), "warning", f"step {h}: {skill} visibly failed; attempt {attempt}")

    def skill_run(self, start: int, skill: Skill, res: Any, idle: int) -> None:
        tool, traj = skill.tool, res.trajectory
        s = start
        self.log.set_tool_pose(self.t(s), s, tool, list(res.approach.position), yaw=float(res.approach.yaw))
        for i, action in enumerate(traj.action):
            self.log.action(self.t(s + 1), s, tool, np.asarray(action, np.float32))
            s += 1
            if s % self.every == 0:
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
                             "diverged": result.diverged is not None})
