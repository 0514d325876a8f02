"""The 'prefix_beam' planner: beam search over skill prefixes, then the shared optimiser on the best full sequences."""

from __future__ import annotations

import dataclasses
import functools
import math
import time
from dataclasses import dataclass

import torch

from pasta.core import CardinalityError, Plan, PlanningProblem, kept_indices
from pasta.planning import LatentPlanner, receding_search, search
from pasta_planner_prefix_beam.config import PrefixBeamConfig


@dataclass
class _Prefix:
    skills: tuple[str, ...]
    states: list[torch.Tensor]  # d + 1 sets: the observed one, then (K_h, D) after each step (new entities first)
    log_feas: list[float]  # d + 1 running sums of log max(f_h, floor) (0 first)
    value: float  # log_feas before its last window + log of that window's search score (set cost to the goal included)


class PrefixBeamPlanner(LatentPlanner):
    """Beam search over skill prefixes (PASTA's objective; the prefix work grows linearly with H and K).

    Depth ``d = 1 .. H``: every kept prefix is extended by every skill that can consume from its set and
    whose count can still reach the goal's within the steps left (cardinality pruning). The children of
    one parent are scored in one :func:`pasta.planning.search` call: the last ``window`` steps of each
    child are optimised from the set the parent reached before them (``start=``: the warm start; the
    earlier steps stay as the parent committed them), ``prefix_samples`` samples x ``prefix_iterations``.
    A child's value is ``sum_h log max(f_h, floor)`` of the steps before its window plus the log of its
    window's search score, whose set cost of the end set to the goal (``min(K, G)`` pairs matched) is the
    estimate of the rest. The best ``width`` children of each entity count are kept (a set with fewer
    entities than the goal leaves goal entities unmatched, so values are only compared between prefixes
    of the same count). Every child whose entity count equals the goal's is a complete candidate (only
    length ``H``, or with ``max_horizon = N > 0`` any length ``1..N``, as ``exhaustive``); the ``final``
    best of them are optimised jointly from the observed set with ``num_samples`` x ``iterations`` (the
    same :func:`search` and objective as ``exhaustive``), and the best wins; with ``finish=receding``
    they are searched a window of ``finish_window`` steps at a time instead (:func:`receding_search`,
    as ``receding_horizon`` does: better sub-goals for the first steps of long plans); ``finish=hybrid``
    takes the skeleton the joint search chose and plans its sub-goals with :func:`receding_search`. A given
    ``problem.skeleton`` skips the beam (and with ``finish=receding`` plans as ``receding_horizon``). At
    most ``width * C`` searches per depth (``C`` entity counts), each over at most ``K`` sequences of
    ``window`` steps, instead of ``K^H`` sequences.
    """

    name = "prefix_beam"
    method = "adam"
    config_class = PrefixBeamConfig

    def plan(self, problem: PlanningProblem) -> Plan:
        cfg = self.cfg
        gen = self.generator(problem)
        t0 = time.perf_counter()
        timings = {"enumerate": 0.0, "beam": 0.0, "sample": 0.0, "optimise": 0.0}
        if problem.skeleton is not None:
            sequences, stages = problem.skeletons(), []  # the given skeleton (cardinality checked)
        else:
            sequences, stages, prefix_timings = self._beam(problem, gen)
            timings["beam"] = prefix_timings
        results, receding = [], None
        if cfg.finish != "receding":  # jointly, as exhaustive optimises each sequence
            results.append(search(problem, sequences, cfg, gen, method=self.method))
        if cfg.finish != "joint":  # a window at a time from the observed set: "receding" over the kept
            # sequences, "hybrid" over the one the joint search chose (its skeleton, receding sub-goals)
            chosen = [results[0].skeleton] if results else sequences
            receding = receding_search(problem, chosen, cfg, gen, window=int(cfg.finish_window), method=self.method)
            results += receding.results
        result = receding if receding is not None else results[0]
        for key in ("sample", "optimise"):
            timings[key] = sum(r.timings[key] for r in results)
        timings["enumerate"] = time.perf_counter() - t0 - sum(timings.values())
        info = self.info(sequences, results)
        if receding is not None:
            info["finish"] = {"mode": str(cfg.finish), "window": int(cfg.finish_window), "stages": receding.stages()}
        info["beam"] = {"width": int(cfg.width), "final": int(cfg.final), "prefix_samples": int(cfg.prefix_samples),
                        "prefix_iterations": int(cfg.prefix_iterations), "max_horizon": int(cfg.max_horizon),
                        "prefix_searches": sum(s["searches"] for s in stages),
                        "prefixes": sum(s["expanded"] for s in stages),
                        "prefix_evaluations": sum(s["evaluations"] for s in stages), "stages": stages}
        return self.package(problem, result.skeleton, result.attention, result.subgoals, timings=timings, info=info)

    def _beam(self, problem: PlanningProblem, gen: torch.Generator) -> tuple[list[tuple[str, ...]], list[dict], float]:
        cfg = self.cfg
        t0 = time.perf_counter()
        specs = [s.spec for s in problem.skills]
        k_goal, floor = len(problem.goal), float(cfg.feasibility_floor)
        exact = int(cfg.max_horizon) <= 0
        horizon = int(problem.horizon) if exact else int(cfg.max_horizon)

        @functools.lru_cache(maxsize=None)
        def reaches(k: int, steps: int) -> bool:
            """Can ``k`` entities become ``k_goal`` in exactly ``steps`` steps?"""
            if steps == 0:
                return k == k_goal
            return any(k >= s.n_in and reaches(k + s.delta, steps - 1) for s in specs)

        def can_finish(k: int, left: int) -> bool:
            return reaches(k, left) if exact else any(reaches(k, j) for j in range(left + 1))

        if not any(reaches(len(problem.obs), h) for h in (range(horizon, horizon + 1) if exact else range(1, horizon + 1))):
            raise CardinalityError(
                f"no sequence of {'' if exact else '1 to '}{horizon} skills turns {len(problem.obs)} observed entities "
                f"into {k_goal} goal entities; skill cardinalities (N_k -> M_k): "
                + ", ".join(f"{s.name} {s.n_in}->{s.n_out}" for s in specs))
        # prefix searches only rank children for the beam; the final search over the kept sequences refines
        pcfg = dataclasses.replace(cfg, num_samples=int(cfg.prefix_samples), iterations=int(cfg.prefix_iterations),
                                   refine_sequences=0)
        beam = [_Prefix((), [problem.obs], [0.0], 0.0)]
        complete: dict[tuple[str, ...], float] = {}
        stages: list[dict] = []
        for depth in range(1, horizon + 1):
            children: list[_Prefix] = []
            evaluations = searches = 0
            lo = max(0, depth - int(cfg.window))
            for parent in beam:
                k = parent.states[-1].shape[0]
                names = [sp.name for sp in specs if k >= sp.n_in and can_finish(k + sp.delta, horizon - depth)]
                if not names:
                    continue
                # one search for all children of this parent: they share the start set parent.states[lo]
                res = search(problem, [(parent.skills + (n,))[lo:] for n in names], pcfg, gen, method=self.method,
                             start=parent.states[lo])
                evaluations += res.evaluations
                searches += 1
                found = {tuple(b[0]): b for b in res.best if b is not None}  # keyed by window, whatever the order
                for name in names:
                    best = found.get((parent.skills + (name,))[lo:])
                    if best is None:
                        continue
                    window_skills, window_attention, window_subgoals, score = best
                    skills = parent.skills + (name,)
                    states, log_feas = list(parent.states[: lo + 1]), list(parent.log_feas[: lo + 1])
                    with torch.no_grad():
                        for step, inputs, new in zip(window_skills, window_attention, window_subgoals):
                            state, inputs = states[-1], list(inputs)
                            f = float(problem.skill_map[step].feasibility(state[inputs].unsqueeze(0), new.unsqueeze(0))[0])
                            states.append(torch.cat([new, state[list(kept_indices(len(state), inputs))]], 0))
                            log_feas.append(log_feas[-1] + math.log(max(f, floor)))
                    child = _Prefix(skills, states, log_feas, log_feas[lo] + math.log(max(score, 1e-300)))
                    children.append(child)
                    if len(states[-1]) == k_goal and (not exact or depth == horizon):
                        complete[child.skills] = child.value
            order = sorted(range(len(children)), key=lambda i: -children[i].value)  # stable: ties keep order
            # the best `width` per entity count: the partial set cost ignores unmatched goal entities, so
            # prefixes with fewer entities than the goal look better than they are and must not crowd out
            # the others
            kept, per_count = [], {}
            for i in order:
                n = len(children[i].states[-1])
                if per_count.get(n, 0) < int(cfg.width):
                    per_count[n] = per_count.get(n, 0) + 1
                    kept.append(i)
            beam = [children[i] for i in kept] if depth < horizon else []
            stages.append({"depth": depth, "expanded": len(children), "searches": searches, "evaluations": evaluations,
                           "kept": [list(children[i].skills) for i in kept],
                           "ranked": [{"skills": list(children[i].skills), "value": children[i].value} for i in order]})
            if not beam:
                break
        best = sorted(complete, key=lambda s: -complete[s])[: int(cfg.final)]
        return best, stages, time.perf_counter() - t0
