"""One perceive -> plan -> check path for ``pasta plan``, ``pasta run`` and ``pasta eval``, and one episode.

- :func:`perceive`: decompose a dough cloud into entities (DBSCAN, ``perception.*``) and encode them.
- :func:`perceive_and_plan`: perceive the observation and the goal, check the entities against the models'
  training boxes, build the planning problem (pieces already at a goal piece are kept out of the search),
  plan, and check the plan: a planner that raises or returns something other than a valid
  :class:`~pasta.core.Plan` is refused here, for every command alike, before anything is executed or
  written. The plan carries its confidence report and flags (``plan.info``).
- :func:`run_episode`: :func:`perceive_and_plan` from a simulator's observation, then
  :func:`pasta.execute.execute_plan`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from contextlib import nullcontext
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from pasta.config.run import CheckConfig, ExecuteConfig, PerceptionConfig
from pasta.core import progress
from pasta.core.errors import InputError, PastaError, PluginRuntimeError, UnreachableGoalError
from pasta.core.plan import Plan
from pasta.execute.executor import ExecutionResult, execute_plan

__all__ = ["Episode", "Perceived", "check_training_box", "confidence", "latent_distances", "perceive",
           "perceive_and_plan", "run_episode"]


@dataclass
class Perceived:
    """What :func:`perceive_and_plan` saw and planned.

    Attributes:
        plan: the checked plan, with ``info["confidence"]`` and ``info["flags"]``.
        entities: ``{"obs", "goal"}`` -> the entity clouds, each ``(num_points, 3)``.
        labels: ``{"obs", "goal"}`` -> ``(P,)`` the entity of every point of the cloud that was decomposed.
        clouds: ``{"obs", "goal"}`` -> the clouds that were decomposed (after voxel downsampling).
        latents: ``{"obs", "goal"}`` -> ``(K, D)`` torch latents.
        flags: the plan's flags (``kind`` ``unreachable`` or ``out_of_distribution``, ``message``).
    """

    plan: Plan
    entities: dict[str, list[np.ndarray]]
    labels: dict[str, np.ndarray]
    clouds: dict[str, np.ndarray]
    latents: dict[str, Any]
    flags: list[dict[str, str]] = field(default_factory=list)

    @property
    def unreachable(self) -> bool:
        """A flag says the plan probably cannot reach the goal (``pasta plan`` exits 3)."""
        return any(f["kind"] == "unreachable" for f in self.flags)


def perceive(points: np.ndarray, encoder: Any, perception: PerceptionConfig | None = None, *,
             seed: int = 0, labels: np.ndarray | None = None) -> tuple[list[np.ndarray], np.ndarray, np.ndarray, Any]:
    """Entities of ``points (P, 3)`` and their latents; ``labels (P,)``: the entity of every point as the caller
    already knows it (the closed loop's joined pieces) instead of a decomposition.

    Returns ``(entities, each (num_points, 3); labels (Q,) of the decomposed cloud; that cloud (Q, 3);
    latents (K, D) torch)``. A cloud above ``perception.max_points`` is voxel-downsampled first. An encoder
    of ``scope == "scene"`` (the Flat 3D baseline) gets the whole cloud as one entity.
    """
    import torch

    from pasta.core.decompose import decompose_labels, resample, voxel_downsample

    perception = perception or PerceptionConfig()
    pts = np.asarray(points, np.float32)
    if labels is not None and len(labels) != len(pts):
        raise InputError(f"labels has {len(labels)} entries for {len(pts)} points")
    if len(pts) > perception.max_points and labels is None:
        pts = voxel_downsample(pts, perception.max_points)[0]
    rng = np.random.default_rng(seed)
    if getattr(encoder, "scope", "entity") == "scene":  # Flat 3D: the whole cloud is the one entity
        labels = np.zeros(len(pts), np.int64)
        entities = [pts[rng.choice(len(pts), perception.num_points, replace=len(pts) < perception.num_points)]]
    else:
        labels = decompose_labels(pts, **perception.decompose_kwargs()) if labels is None else np.asarray(labels)
        entities = [resample(pts[labels == k], perception.num_points, rng) for k in range(int(labels.max()) + 1)]
    with torch.no_grad():
        latents = encoder.encode(torch.as_tensor(np.stack(entities))).detach().cpu().float()
    return entities, labels, pts, latents


def check_volumes(clouds: dict[str, np.ndarray], labels: dict[str, np.ndarray] | None, check: CheckConfig,
                  perception: PerceptionConfig) -> dict[str, float]:
    """The dough volume (m^3) of the ``obs`` and ``goal`` clouds, each the summed convex hulls of its pieces
    (``labels``, or decomposed here for a whole-scene encoder); raises :class:`UnreachableGoalError` when the
    goal's is outside ``[1 / check.volume_ratio, check.volume_ratio]`` times the observation's."""
    from pasta.core.decompose import decompose_labels
    from pasta.perception.volume import piece_volumes, volume_ratio

    volume = {}
    for name in ("obs", "goal"):
        lab = labels[name] if labels is not None else decompose_labels(clouds[name], **perception.decompose_kwargs())
        volume[name] = float(piece_volumes(clouds[name], lab).sum())
    ratio, limit = volume_ratio(volume["goal"], volume["obs"]), float(check.volume_ratio)
    if not 1.0 / limit <= ratio <= limit:
        raise UnreachableGoalError(
            f"the goal holds {ratio:.3g} times the observed dough ({1e6 * volume['goal']:.1f} cm^3 against "
            f"{1e6 * volume['obs']:.1f} cm^3, summed convex hulls of the pieces), outside 1/{limit:g} to {limit:g} "
            f"(check.volume_ratio): skills move and shape dough, they neither add nor remove it")
    return volume


def perceive_and_plan(obs: np.ndarray, goal: np.ndarray, *, planner: Any, skills: Sequence[Any], encoder: Any,
                      cost: Any, horizon: int, seed: int = 0, skeleton: Sequence[str] | None = None,
                      perception: PerceptionConfig | None = None, check: CheckConfig | None = None,
                      planner_name: str = "", encoder_name: str = "",
                      candidates: Sequence[Sequence[str]] = (), obs_labels: np.ndarray | None = None) -> Perceived:
    """Perceive ``obs (P, 3)`` and ``goal (G, 3)``, plan ``horizon`` steps with ``planner`` and check the plan.

    Observed entities within ``perception.unchanged_threshold`` (Chamfer) of a goal entity are that goal
    piece already (``PlanningProblem.fixed``: never attended, matched to it).

    Raises:
        InputError: an entity outside the models' training boxes (more than ``check.box_margin``), latents
            that are not finite, or a plan that fails :meth:`pasta.core.Plan.check`.
        UnreachableGoalError: the goal holds more than ``check.volume_ratio`` times the observation's dough,
            or less than its inverse (:func:`check_volumes`).
        PluginRuntimeError: the planner raised, or returned something other than a ``Plan``; the message
            names the planner and its distribution.
    """
    from pasta.core.matching import unchanged_pairs
    from pasta.core.planner import PlanningProblem
    from pasta.core.shapes import check_latents
    from pasta.planning.batch import training_boxes

    perception = perception or PerceptionConfig()
    check = check or CheckConfig()
    scene = getattr(encoder, "scope", "entity") == "scene"  # Flat 3D: one entity, no training boxes per piece
    boxes = training_boxes(encoder, skills)
    entities, labels, clouds, latents = {}, {}, {}, {}
    box_flags: list[dict[str, str]] = []
    for name, points in (("obs", obs), ("goal", goal)):
        entities[name], labels[name], clouds[name], u = perceive(points, encoder, perception, seed=seed,
                                                                 labels=obs_labels if name == "obs" else None)
        who = f" (encoder {encoder_name!r})" if encoder_name else ""
        latents[name] = check_latents(u, f"the {len(entities[name])} encoded {name} entities{who}", dim=encoder.latent_dim)
        if not scene:
            box_flags += check_training_box(latents[name], encoder, name, check.box_margin, boxes=boxes)
    check_volumes(clouds, None if scene else labels, check, perception)  # before planning: no plan reaches it
    fixed = () if scene else unchanged_pairs(np.stack(entities["obs"]), np.stack(entities["goal"]),
                                             threshold=perception.unchanged_threshold)
    problem = PlanningProblem(obs=latents["obs"], goal=latents["goal"], skills=list(skills), encoder=encoder,
                              cost=cost, horizon=horizon, seed=seed, skeleton=tuple(skeleton) if skeleton else None,
                              fixed=tuple(fixed), candidates=tuple(tuple(c) for c in candidates))
    plan = _plan(planner, problem, planner_name)
    report = confidence(plan, encoder, latents, check, skills)
    flags = box_flags + report["flags"]
    plan = dataclasses.replace(plan, info={**plan.info, "confidence": report["confidence"], "flags": flags})
    return Perceived(plan, entities, labels, clouds, latents, flags)


def _plan(planner: Any, problem: Any, name: str) -> Plan:
    """``planner.plan(problem)``, checked; a planner that fails at work is named with its distribution."""
    who = _planner_origin(planner, name)
    try:
        plan = planner.plan(problem)
    except PastaError:  # the planner refused the problem for a reason it names (no sequence fits, ...)
        raise
    except Exception as exc:
        raise PluginRuntimeError(f"{who} raised {type(exc).__name__}: {exc}") from exc
    if not isinstance(plan, Plan):
        raise PluginRuntimeError(f"{who} returned {type(plan).__name__}, not a pasta.core.Plan")
    return plan.check()  # a NaN or out-of-range score/latent is refused, not executed or written


def _planner_origin(planner: Any, name: str) -> str:
    """``planner 'NAME' (plugin 'P' from DIST VERSION)`` for messages."""
    name = name or str(getattr(planner, "name", "") or type(planner).__name__)
    try:
        from pasta.plugins import get_plugins

        return f"planner '{name}' ({get_plugins(report=False).planners.info(name).origin})"
    except PastaError:  # not a registered planner (built in-process)
        return f"planner '{name}' ({type(planner).__module__}.{type(planner).__name__})"


def _outside(t: Any, boxes: Any, margin: float = 0.0) -> tuple[Any, Any]:
    """Per centroid ``t (K, 3)``: the per-axis distance ``(K, 3)`` outside its nearest box (more than
    ``margin`` out), and that box's index ``(K,)``."""
    per_box = np.stack([np.maximum(np.asarray(lo) - margin - t, 0) + np.maximum(t - np.asarray(hi) - margin, 0)
                        for lo, hi in boxes])  # (B, K, 3)
    nearest = np.argmin(np.linalg.norm(per_box, axis=2), axis=0)
    return per_box[nearest, np.arange(len(t))], nearest


def check_training_box(latents: Any, encoder: Any, name: str, margin: float, boxes: Any = None) -> list[dict[str, str]]:
    """Check the centroids ``t`` of ``latents (K, D)`` against ``boxes`` (default: the encoder's box of
    training centroids; :func:`pasta.planning.batch.training_boxes` adds the skills' own).

    A piece's height is set by what it rests on (the table, the raised board): a centroid more than
    ``margin`` above or below the heights of every box means the cloud is not what the models can read (a
    top-down camera view whose centroids sit high, a wrong up axis or table height), and is refused. A piece
    elsewhere on the table than the training pieces lay (crs_twice pushes pieces up to 9 cm past them in z)
    is legitimate input the models extrapolate to; the planner clamps its sub-goals into the box, so it gets
    an ``out_of_distribution`` flag (returned) instead.

    Raises:
        InputError: a centroid out of every box's heights by more than ``margin``.
    """
    t = latents[:, encoder.z_dim:].detach().cpu().numpy().astype(np.float64)
    boxes = boxes or [(encoder.t_low, encoder.t_high)]
    outside, nearest = _outside(t, boxes, margin)
    heights = [(lo[1], hi[1]) for lo, hi in boxes]
    off = np.array([min(max(lo - margin - y, y - hi - margin, 0.0) for lo, hi in heights) for y in t[:, 1]])
    bad = np.flatnonzero(off > 0)
    if len(bad):
        k = int(bad[np.argmax(off[bad])])
        low, high = boxes[int(nearest[k])]
        box = ", ".join(f"{a} {lo:.3f}..{hi:.3f}" for a, lo, hi in zip("xyz", low, high))
        more = f" (the nearest of {len(boxes)}: the encoder's and the skills' own)" if len(boxes) > 1 else ""
        raise InputError(f"{name} cloud: {len(bad)} of {len(t)} pieces lie outside the box the models were trained on "
                         f"(piece {k} centroid ({t[k, 0]:.3f}, {t[k, 1]:.3f}, {t[k, 2]:.3f}) is {off[k]:.3f} "
                         f"out in y; box {box}{more}, check.box_margin={margin:g}); a top-down camera view needs "
                         "preprocess=camera, another frame units=, up=, transform=")
    far = [f"piece {k} ({t[k, 0]:.3f}, {t[k, 1]:.3f}, {t[k, 2]:.3f}) {outside[k].max():.3f} out in "
           f"{'xyz'[int(np.argmax(outside[k]))]}" for k in np.flatnonzero(outside.max(1) > 0)]
    if not far:
        return []
    return [{"kind": "out_of_distribution", "message": f"{name} cloud: {'; '.join(far)} of the boxes the models were "
             f"trained on (check.box_margin={margin:g}): the planner clamps sub-goals into them"}]


def latent_distances(latents: Any, encoder: Any, boxes: Any = None) -> list[dict[str, float]]:
    """Per latent ``(K, D)``: ``z_norm`` (Mahalanobis distance of ``z`` under the prior N(0, I)) and
    ``t_outside`` (metres of ``t`` outside the nearest of ``boxes``, default the encoder's box of training
    centroids; 0 inside one)."""
    u = np.asarray(latents, dtype=np.float64).reshape(-1, encoder.latent_dim)
    z, t = u[:, :encoder.z_dim], u[:, encoder.z_dim:]
    out = np.linalg.norm(_outside(t, boxes or [(encoder.t_low, encoder.t_high)])[0], axis=1)
    return [{"z_norm": round(float(a), 6), "t_outside": round(float(b), 6)} for a, b in zip(np.linalg.norm(z, axis=1), out)]


def confidence(plan: Any, encoder: Any, latents: dict, check: CheckConfig, skills: Any = ()) -> dict[str, Any]:
    """How far the plan's latents sit from the training distribution, and the flags it raises.

    Returns ``{"confidence": {...}, "flags": [{"kind", "message"}, ...]}``; kind ``unreachable`` (a step's
    feasibility below ``check.min_feasibility`` or the final cost above ``check.max_cost``) or
    ``out_of_distribution`` (a latent with ``|z|`` above ``check.max_z``).
    """
    from pasta.planning.batch import centroid_box, training_boxes

    boxes = training_boxes(encoder, skills)
    by_name = {sk.name: sk for sk in skills}
    conf: dict[str, Any] = {name: latent_distances(latents[name], encoder, boxes) for name in ("obs", "goal")}
    steps = []
    for step in plan.steps:
        own = [centroid_box(encoder, by_name[step.skill])] if step.skill in by_name else None
        d = latent_distances(step.subgoal, encoder, own)
        steps.append({"skill": step.skill, "feasibility": step.feasibility,
                      "z_norm": max(x["z_norm"] for x in d), "t_outside": max(x["t_outside"] for x in d)})
    conf["steps"] = steps
    conf["min_feasibility"] = min((s["feasibility"] for s in steps), default=1.0)
    conf["final_cost"] = plan.final_cost
    flags = []
    low = [f"{h + 1} ({s['skill']}) {s['feasibility']:.3f}" for h, s in enumerate(steps)
           if s["feasibility"] < check.min_feasibility]
    if low:
        flags.append({"kind": "unreachable", "message": f"predicted feasibility below check.min_feasibility="
                      f"{check.min_feasibility:g} at step {', '.join(low)}"})
    if plan.final_cost > check.max_cost:
        flags.append({"kind": "unreachable", "message": f"the final state is predicted {plan.final_cost:.4f} "
                      f"(Chamfer) from the goal, above check.max_cost={check.max_cost:g}"})
    far = [f"{where} {x['z_norm']:.2f}" for where, xs in (("obs", conf["obs"]), ("goal", conf["goal"]),
                                                         *((f"step {h + 1}", [s]) for h, s in enumerate(steps)))
           for x in xs if x["z_norm"] > check.max_z]
    if far:
        flags.append({"kind": "out_of_distribution", "message": f"|z| above check.max_z={check.max_z:g} "
                      f"(prior N(0, I)): {', '.join(far)}"})
    return {"confidence": conf, "flags": flags}


@dataclass
class Episode:
    """A planned and executed episode: what was perceived and planned, and the execution result."""

    perceived: Perceived
    result: ExecutionResult

    @property
    def plan(self) -> Plan:
        return self.perceived.plan


def run_episode(sim: Any, goal: np.ndarray, *, planner: Any, skills: Sequence[Any], encoder: Any, cost: Any,
                horizon: int, seed: int = 0, skeleton: Sequence[str] | None = None,
                cfg: ExecuteConfig | None = None, perception: PerceptionConfig | None = None,
                check: CheckConfig | None = None, planner_name: str = "", emd_points: int = 500, emd_seed: int = 0,
                logger: Any = None, disturb: str = "") -> Episode:
    """Plan from ``sim``'s current observation to ``goal (G, 3)`` (:func:`perceive_and_plan`) and execute.
    ``logger`` (a :class:`pasta.io.RunLogger`) records the planner's progress on ``/planner/progress`` too.
    ``disturb``: a disturbance after the first step (:func:`pasta.execute.execute_plan`); with
    ``cfg.loop="closed"`` a plan that no longer fits is re-planned (:func:`replanner`)."""
    cfg = cfg or ExecuteConfig()
    plan_args = {"planner": planner, "skills": skills, "encoder": encoder, "cost": cost, "perception": perception,
                 "check": check, "planner_name": planner_name}
    with progress.listening(_progress_logger(logger, sim)) if logger is not None else nullcontext():
        perceived = perceive_and_plan(sim.observe().dough, goal, horizon=horizon, seed=seed, skeleton=skeleton,
                                      **plan_args)
    replan = replanner(goal, seed=seed, **plan_args) if cfg.loop == "closed" else None
    result = execute_plan(sim, perceived.plan, skills={s.name: s for s in skills}, encoder=encoder, goal=goal,
                          cfg=cfg, perception=perception, emd_points=emd_points, emd_seed=emd_seed, logger=logger,
                          disturb=disturb, seed=seed, replan=replan)
    return Episode(perceived, result)


def replanner(goal: np.ndarray, *, seed: int = 0,
              **plan_args: Any) -> Callable[[np.ndarray, Plan, set[int], np.ndarray | None], Plan]:
    """The closed loop's re-planner: ``(observed dough, plan, executed steps, its entity labels or None) ->
    plan`` of the remaining steps, warm-started from ``plan``, from what is observed now, in two stages:

    1. the remaining skill sequence alone; kept when it reaches the goal's piece count and its predicted final
       cost is at most :data:`REPLAN_COST_RATIO` times the current plan's (the disturbance changed where the
       steps go, not which steps are needed);
    2. otherwise every sequence with one more skill inserted (:func:`pasta.execute.loop.warm_start_sequences`),
       and the better of the two stages by the planner's score.

    ``plan_args``: the planner, skills, models and checks of :func:`perceive_and_plan`."""
    from pasta.core.errors import CardinalityError
    from pasta.execute.loop import remaining_skills, warm_start_sequences

    names = [s.name for s in plan_args["skills"]]

    def replan(dough: np.ndarray, plan: Plan, executed: set[int], labels: np.ndarray | None = None) -> Plan:
        remaining = remaining_skills(plan, executed)

        def search(candidates: Sequence[Sequence[str]]) -> Plan:
            return perceive_and_plan(dough, goal, horizon=len(remaining), seed=seed, obs_labels=labels,
                                     candidates=candidates, **plan_args).plan

        same = None
        try:
            same = search([remaining])
        except CardinalityError:
            pass
        if same is not None and same.final_cost <= REPLAN_COST_RATIO * max(float(plan.final_cost), 1e-9):
            return same
        try:
            longer = search(warm_start_sequences(remaining, names)[1:])
        except CardinalityError:
            if same is None:
                raise
            return same
        return longer if same is None or longer.score > same.score else same

    return replan


#: a re-plan keeps the remaining skill sequence when its predicted final cost is at most this many times the
#: current plan's (:func:`replanner`)
REPLAN_COST_RATIO = 2.0


def _progress_logger(logger: Any, sim: Any) -> Any:
    """A progress listener that writes each report to ``/planner/progress`` at the simulator's current time
    (with ``clock=wall`` the logger stamps the wall clock instead, so planning spans its real length)."""
    from pasta.io import step_time_ns

    t = step_time_ns(sim.step_count, sim.cfg.dt * sim.cfg.substeps)

    def write(event: progress.Progress) -> None:
        logger.planner_progress(t, {"stage": event.stage, "iteration": event.done, "iterations": event.total,
                                    **{k: v for k, v in event.info.items()
                                       if isinstance(v, str) or (isinstance(v, (int, float)) and math.isfinite(v))}})

    return write
