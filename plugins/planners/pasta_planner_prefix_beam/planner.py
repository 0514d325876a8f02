"""The 'prefix_beam' planner: beam search over skill prefixes, then the shared optimiser on the best full sequences."""

from __future__ import annotations

import dataclasses
import functools
import math
import time
from dataclasses import dataclass

import torch

from pasta.core import CardinalityError, Plan, PlanningProblem, check_skeleton, kept_indices, toward_goal
from pasta.planning import FLOOR, LatentPlanner, SearchResult, search
from pasta.planning.batch import free_feasible
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
    same :func:`search` and objective as ``exhaustive``), and the best wins. With ``polish = R > 0`` the
    joint search is followed by up to ``R`` rounds of local search over sequences one edit away from the
    best found (:meth:`_polish`), which recovers full sequences whose prefixes the beam dropped on noisy
    values. A given ``problem.skeleton`` skips the beam. At most ``width * C`` searches per depth (``C`` entity counts), each over at most ``K`` sequences of
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
        stages: list[dict]
        if problem.sequences_given:
            sequences, stages = problem.skeletons(), []  # the given skeleton or candidates (cardinality checked)
        else:
            sequences, stages, prefix_timings = self._beam(problem, gen)
            timings["beam"] = prefix_timings
        results: list[SearchResult] = []
        polish: list[dict] = []
        if int(cfg.polish) > 0 and not problem.sequences_given:
            results += self._polish(problem, sequences, gen, polish)
        else:
            results.append(search(problem, sequences, cfg, gen, method=self.method))
        result = results[-1]
        for key in ("sample", "optimise"):
            timings[key] = sum(r.timings[key] for r in results)
        timings["enumerate"] = time.perf_counter() - t0 - sum(timings.values())
        info = self.info(sequences, results)
        info["beam"] = {"width": int(cfg.width), "final": int(cfg.final), "prefix_samples": int(cfg.prefix_samples),
                        "prefix_iterations": int(cfg.prefix_iterations), "max_horizon": int(cfg.max_horizon),
                        "prefix_searches": sum(s["searches"] for s in stages),
                        "prefixes": sum(s["expanded"] for s in stages),
                        "prefix_evaluations": sum(s["evaluations"] for s in stages), "stages": stages}
        if polish:
            info["polish"] = polish
        return self.package(problem, result.skeleton, result.attention, result.subgoals, timings=timings, info=info)

    def _polish(self, problem: PlanningProblem, sequences: list[tuple[str, ...]], gen: torch.Generator,
                rounds: list[dict]) -> list[SearchResult]:
        """Local search around the beam's best complete sequences; returns the searches, the deciding one last.

        The beam ranks prefixes by values that differ by less than their sampling noise, so the best full
        sequence can be one edit away from every kept one (a push inserted before the cut, a second
        roll). Each round searches, with the final settings and no refinement, every sequence one edit
        away (insert, delete or substitute one skill, or swap two neighbours) from the ``polish_top`` best
        searched so far that can still turn the observed count into the goal's and was not searched yet;
        it stops when there is none (the best are a local optimum) or after ``polish`` rounds. The best
        ``refine_sequences + 1`` are then searched once more with the final settings (their refinement
        included), so the winner is chosen as :func:`search` would choose it among all searched sequences.
        ``rounds`` receives one ``{"searched", "best", "score"}`` entry per round.
        """
        cfg = self.cfg
        plain = dataclasses.replace(cfg, refine_sequences=0)
        results = [search(problem, sequences, plain, gen, method=self.method)]
        scores: dict[tuple[str, ...], float] = {}

        def record(result: SearchResult) -> None:
            for row, best in zip(result.per_sequence, result.best):
                if best is not None:
                    scores[tuple(row["skills"])] = float(best[3])

        def ranked() -> list[tuple[str, ...]]:
            return sorted(scores, key=lambda s: -scores[s])  # stable: ties keep the order searched

        record(results[0])
        if not scores:  # no sequence kept a sample: nothing to search around
            return results
        seen = set(map(tuple, sequences))
        complete, names, fixed = self._completes(problem), [sk.spec.name for sk in problem.skills], results[0].fixed

        def valid(skills: tuple[str, ...]) -> bool:  # as the searches treat them: entities at their goal stay
            if not complete(skills):
                return False
            return not fixed or free_feasible(skills, problem.skill_map, len(problem.obs), len(fixed))

        for _ in range(int(cfg.polish)):
            fresh = list(dict.fromkeys(n for s in ranked()[: int(cfg.polish_top)] for n in _neighbours(s, names)
                                       if n not in seen and valid(n)))
            if not fresh:
                break
            seen.update(fresh)
            results.append(search(problem, fresh, plain, gen, method=self.method))
            record(results[-1])
            best = ranked()[0]
            rounds.append({"searched": len(fresh), "best": list(best), "score": scores[best]})
        results.append(search(problem, ranked()[: int(cfg.refine_sequences) + 1], cfg, gen, method=self.method))
        return results

    def _lengths(self, problem: PlanningProblem) -> tuple[bool, int]:
        """``(exact, horizon)``: only sequences of the problem's horizon (``max_horizon`` 0), or any length up to
        ``max_horizon``."""
        exact = int(self.cfg.max_horizon) <= 0
        return exact, int(problem.horizon) if exact else int(self.cfg.max_horizon)

    def _completes(self, problem: PlanningProblem):
        """A test: does a skill sequence turn the observed entities into the goal's count (within the horizon)?"""
        exact, horizon = self._lengths(problem)
        specs = [s.spec for s in problem.skills]

        def valid(skills: tuple[str, ...]) -> bool:
            if not skills or len(skills) > horizon or (exact and len(skills) != horizon):
                return False
            try:
                check_skeleton(skills, specs, len(problem.obs), len(problem.goal))
            except CardinalityError:
                return False
            return True

        return valid

    def _beam(self, problem: PlanningProblem, gen: torch.Generator) -> tuple[list[tuple[str, ...]], list[dict], float]:
        cfg = self.cfg
        t0 = time.perf_counter()
        specs = [s.spec for s in problem.skills]
        k_goal, floor = len(problem.goal), FLOOR
        exact, horizon = self._lengths(problem)

        @functools.cache
        def reaches(k: int, steps: int) -> bool:
            """Can ``k`` entities become ``k_goal`` in exactly ``steps`` steps?"""
            if steps == 0:
                return k == k_goal
            return any(k >= s.n_in and toward_goal(k, s.delta, k_goal) and reaches(k + s.delta, steps - 1) for s in specs)

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
                names = [sp.name for sp in specs
                         if k >= sp.n_in and toward_goal(k, sp.delta, k_goal) and can_finish(k + sp.delta, horizon - depth)]
                if not names:
                    continue
                # one search for all children of this parent: they share the start set parent.states[lo]
                res = search(problem, [(*parent.skills, n)[lo:] for n in names], pcfg, gen, method=self.method,
                             start=parent.states[lo])
                evaluations += res.evaluations
                searches += 1
                found = {tuple(b[0]): b for b in res.best if b is not None}  # keyed by window, whatever the order
                for name in names:
                    best = found.get((*parent.skills, name)[lo:])
                    if best is None:
                        continue
                    window_skills, window_attention, window_subgoals, score = best
                    skills = (*parent.skills, name)
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
            kept: list[int] = []
            per_count: dict[int, int] = {}
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


def _neighbours(skills: tuple[str, ...], names) -> list[tuple[str, ...]]:
    """Skill sequences one edit from ``skills``: one skill inserted, deleted or replaced, or two neighbours swapped."""
    out = []
    for i in range(len(skills) + 1):
        out += [(*skills[:i], n, *skills[i:]) for n in names]
    for i in range(len(skills)):
        out.append(skills[:i] + skills[i + 1:])
        out += [(*skills[:i], n, *skills[i + 1:]) for n in names if n != skills[i]]
    for i in range(len(skills) - 1):
        if skills[i] != skills[i + 1]:
            out.append((*skills[:i], skills[i + 1], skills[i], *skills[i + 2:]))
    return list(dict.fromkeys(out))
