"""The latent plan optimiser shared by every planner.

:func:`search` takes a start set, a goal set and a list of skill sequences, draws ``num_samples``
candidates per sequence (random attention per sample and step, sampled once; sub-goal latents from the
encoder prior) and improves all of them at once, either with Adam on the sub-goal latents
(``method="adam"``, PASTA) or with the cross-entropy method (``method="cem"``, the paper's
"no gradient" ablation). With ``planner.clearance_weight > 0`` the plan cost also counts pieces moved
through other pieces (:mod:`pasta.planning.clearance`). Every iteration evaluates all samples of all sequences with
:func:`pasta.planning.batch.evaluate` (one feasibility call per skill, one cost-model call); ``t`` is
projected into the encoder's centroid box after every update. The best sample by plan score wins.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, cast

import torch

from pasta.core import PlanningProblem
from pasta.core import progress
from pasta.core.errors import ConfigError
from pasta.planning.batch import CandidateBatch, FrozenMatching, evaluate, free_feasible, sample_candidates
from pasta.planning.clearance import Clearance
from pasta.planning.config import LatentPlannerConfig
from pasta.planning.objective import log_objective, plan_score

METHODS = ("adam", "cem")
_ADAM_BETAS = (0.9, 0.999)


@dataclass
class SearchResult:
    """The best candidate of a :func:`search` and what it cost.

    Attributes:
        skeleton: skill names of the winner; ``attention``: its consumed indices per step;
        subgoals: its ``(M_h, D)`` latents per step.
        score: its plan score in the batched evaluation.
        per_sequence: for every sequence, ``{"skills", "score" (best), "samples" (left at the end)}``.
        samples: candidates drawn; ``evaluations``: sample evaluations over all iterations.
        timings: seconds spent drawing candidates (``sample``) and optimising (``optimise``).
        best: for every sequence (in ``sequences`` order), its best candidate as ``(skeleton, attention,
            subgoals, score)`` (the winner is the best of these); ``None`` for a sequence left without samples.
        fixed: the ``(start row, goal index)`` pairs kept out of the attention and matched exactly
            (empty when none were given or no sequence could run without them).
    """

    skeleton: tuple[str, ...]
    attention: list[tuple[int, ...]]
    subgoals: list[torch.Tensor]
    score: float
    per_sequence: list[dict[str, Any]]
    samples: int
    evaluations: int
    timings: dict[str, float] = field(default_factory=dict)
    best: list[tuple[tuple[str, ...], list[tuple[int, ...]], list[torch.Tensor], float] | None] = field(default_factory=list)
    fixed: tuple[tuple[int, int], ...] = ()


def search(
    problem: PlanningProblem,
    sequences: Sequence[Sequence[str]],
    config: LatentPlannerConfig,
    generator: torch.Generator,
    *,
    method: str = "adam",
    start: torch.Tensor | None = None,
    elite_fraction: float = 0.1,
    min_std: float = 1e-3,
    fixed: Sequence[tuple[int, int]] | None = None,
) -> SearchResult:
    """Optimise ``config.num_samples`` candidates per sequence and return the best.

    With ``config.refine_sequences = R > 0`` and more than ``R`` sequences, the ``R`` best sequences are
    then optimised once more from fresh candidates and each keeps its better result (:func:`_refine`).

    Args:
        problem: gives the skills, encoder, cost model and goal ``(G, D)``.
        sequences: skill-name sequences, any lengths; each must be able to consume at every step.
        generator: seeded source of every random draw (attention, prior latents, CEM noise).
        method: ``"adam"`` or ``"cem"``.
        start: ``(K_0, D)`` set to start from (default ``problem.obs``).
        elite_fraction, min_std: CEM only.
        fixed: pairs ``(start row, goal index)`` of entities already at their goal entity (default:
            ``problem.fixed`` when starting from ``problem.obs``, none otherwise). They are never attended
            and are matched to their goal entities in the set cost, so the attention search is over the
            other entities only. Sequences that would have to consume a fixed entity are left out; when
            that leaves none, the search runs without fixed entities.

    Returns:
        :class:`SearchResult`: the best candidate's skeleton, attention (per step, the consumed indices)
        and sub-goals (per step ``(M_h, D)``), ready for :func:`pasta.planning.build_plan`.
    """
    if method not in METHODS:
        raise ConfigError(f"unknown optimisation method {method!r}; choose one of {METHODS}")
    if config.iterations < 0:
        raise ConfigError(f"planner.iterations must be >= 0, got {config.iterations}")
    t0 = time.perf_counter()
    if fixed is None:
        fixed = problem.fixed if start is None else ()
    start = problem.obs if start is None else start
    fixed = tuple(fixed)
    if fixed:
        runnable = [s for s in sequences if free_feasible(s, problem.skill_map, start.shape[0], len(fixed))]
        sequences, fixed = (runnable, fixed) if runnable else (list(sequences), ())
    clearance = None
    if config.clearance_weight > 0:
        clearance = Clearance.from_problem(problem.encoder, start, problem.goal, skills=problem.skills)
    timings = {"sample": 0.0, "optimise": 0.0}

    def optimise(seqs: Sequence[Sequence[str]], refining: bool = False) -> SearchResult:
        t_a = time.perf_counter()
        # "sequence" draws: one stream per (problem seed, round, sequence), see LatentPlannerConfig.draws; the
        # refinement is round 1, so it draws fresh candidates
        sequence_seed = 2 * int(problem.seed) + int(refining) if config.draws == "sequence" else None
        batch = sample_candidates(start, problem.goal, seqs, problem.skill_map, problem.encoder, config.num_samples,
                                  generator, fixed=fixed, attention=config.attention, sequence_seed=sequence_seed)
        drawn = batch.size  # before halving shrinks the batch
        t_b = time.perf_counter()
        opt = _Optimiser(problem, batch, config, generator, method, elite_fraction, min_std, clearance,
                         stage="refine" if refining else "optimise")
        scores = opt.run()
        timings["sample"] += t_b - t_a
        timings["optimise"] += time.perf_counter() - t_b
        res = _select(opt.batch, scores, config.keep_per_sequence)
        res.samples, res.evaluations = drawn, opt.evaluations
        return res

    timings["sample"] += time.perf_counter() - t0  # the fixed-entity filter and the clearance set-up
    result = optimise(sequences)
    if 0 < config.refine_sequences < len(sequences):
        result = _refine(result, sequences, config.refine_sequences, optimise)
    result.timings = timings
    result.fixed = fixed
    return result


def _refine(result: SearchResult, sequences: Sequence[Sequence[str]], count: int, optimise) -> SearchResult:
    """Search the ``count`` best sequences of ``result`` again with fresh candidates; keep each one's better result.

    The winner is then the best over both rounds. ``per_sequence`` rows of refined sequences gain
    ``"refined": True``, their ``samples`` (left at the end) add up and their ``top_scores`` merge.
    """
    scored = [(i, b[3]) for i, b in enumerate(result.best) if b is not None]
    ranked = [i for i, _ in sorted(scored, key=lambda t: -t[1])][:count]
    if not ranked:
        return result
    again = optimise([sequences[i] for i in ranked], refining=True)
    best, per_sequence = list(result.best), [dict(r) for r in result.per_sequence]
    for j, i in enumerate(ranked):
        row, new = per_sequence[i], again.per_sequence[j]
        row["top_scores"] = sorted(row["top_scores"] + new["top_scores"], reverse=True)[: len(row["top_scores"])]
        row["samples"] += new["samples"]
        row["refined"] = True
        first, second = best[i], again.best[j]
        if second is not None and first is not None and second[3] > first[3]:  # ties keep the first round's
            best[i], row["score"] = second, second[3]
    final = [b[3] if b is not None else -math.inf for b in best]
    win = max(range(len(best)), key=lambda i: (final[i], -i))
    winner = best[win]
    assert winner is not None  # a ranked sequence has a best
    skeleton, attention, subgoals, score = winner
    return SearchResult(skeleton, attention, subgoals, score, per_sequence, result.samples + again.samples,
                        result.evaluations + again.evaluations, best=best)


class _Optimiser:
    def __init__(self, problem, batch: CandidateBatch, cfg: LatentPlannerConfig, gen, method, elite_fraction, min_std,
                 clearance: Clearance | None = None, stage: str = "optimise"):
        self.problem, self.batch, self.cfg, self.gen, self.method = problem, batch, cfg, gen, method
        self.stage = stage  # what progress reports call this round (pasta.core.progress)
        self.clearance = clearance
        self.elite_fraction, self.min_std = elite_fraction, min_std
        self.skills, self.cost, self.encoder = problem.skill_map, problem.cost, problem.encoder
        self.frozen: FrozenMatching | None = None
        self.evaluations = 0

    def _objective(self, lat: list[torch.Tensor], grad: bool) -> tuple[list[torch.Tensor], list[torch.Tensor]]:
        cfg = self.cfg
        with torch.set_grad_enabled(grad):
            ev = evaluate(self.batch, lat, self.skills, self.cost, frozen=self.frozen, clearance=self.clearance)
            if self.frozen is None:  # the matching is solved at the first evaluation and then kept (the paper's)
                self.frozen = ev.matching
            # the plan cost: set cost to the goal plus the weighted clearance penalty (zero when off)
            cost = [c + cfg.clearance_weight * p for c, p in zip(ev.cost, ev.penalty)]
            obj = [log_objective(lf, c, cost_weight=cfg.cost_weight) for lf, c in zip(ev.log_feasibility, cost)]
        self.evaluations += self.batch.size
        # Ranking (halving, CEM elites): the log of the unfloored score; the reported score has the floor
        self._log_score = [o.detach() for o in obj]
        scores = [plan_score(lf.detach().exp(), c.detach(), cost_weight=cfg.cost_weight)
                  for lf, c in zip(ev.log_feasibility, cost)]
        return obj, scores

    def run(self) -> list[torch.Tensor]:
        """Optimise in place (``self.batch`` ends with the final latents); return the final scores per group."""
        return self._adam() if self.method == "adam" else self._cem()

    # -- gradient: Adam on the sub-goal latents ----------------------------------------------------
    def _clamp(self, lat: list[torch.Tensor]) -> list[torch.Tensor]:
        """Every group's latents with each centroid in its entity's box (:meth:`Group.clamp`)."""
        return [g.clamp(x, self.encoder) for g, x in zip(self.batch.groups, lat)]

    def _adam(self) -> list[torch.Tensor]:
        cfg, iters = self.cfg, self.cfg.iterations
        lat = self._clamp(self.batch.latents())
        m = [torch.zeros_like(x) for x in lat]
        v = [torch.zeros_like(x) for x in lat]
        milestones = {round(f * iters) for f in getattr(cfg, "halving_points", ()) if 0 < f < 1} - {0, iters}
        b1, b2 = _ADAM_BETAS
        for it in range(iters + 1):
            last = it == iters
            xs = [x.detach().requires_grad_(not last) for x in lat]
            obj, scores = self._objective(xs, grad=not last)
            self._report(it, iters, scores)
            if last:
                break
            total = cast(torch.Tensor, sum(o.sum() for o in obj))  # (obj is never empty)
            grads = torch.autograd.grad(-total, xs, allow_unused=True)
            step = it + 1
            c1, c2 = 1 - b1**step, 1 - b2**step
            new = []
            for x, g, mi, vi in zip(xs, grads, m, v):
                g = torch.zeros_like(x) if g is None else g
                mi.mul_(b1).add_(g, alpha=1 - b1)
                vi.mul_(b2).addcmul_(g, g, value=1 - b2)
                upd = (mi / c1) / ((vi / c2).sqrt() + cfg.adam_eps)
                new.append(x.detach() - cfg.lr * upd)
            lat = self._clamp(new)
            if step in milestones:
                keep = self._halve(self._log_score)
                lat = [x[k] for x, k in zip(lat, keep)]
                m = [x[k] for x, k in zip(m, keep)]
                v = [x[k] for x, k in zip(v, keep)]
        self._store(lat)
        return scores

    def _report(self, it: int, iters: int, scores: list[torch.Tensor]) -> None:
        """Iteration ``it`` of ``iters`` done: the candidates left and the best score so far, to whoever listens."""
        if progress.active():
            best = max((float(s.max()) for s in scores if s.numel()), default=float("nan"))
            progress.report(self.stage, it, iters, samples=self.batch.size, evaluations=self.evaluations,
                            best_score=best)

    def _halve(self, obj: list[torch.Tensor]) -> list[torch.Tensor]:
        """Keep the better half (all sequences together) plus each sequence's best few; shrink the batch."""
        values = torch.cat(obj)
        seq = torch.cat([g.seq for g in self.batch.groups])
        keep = torch.zeros(values.shape[0], dtype=torch.bool)
        rank = _rank_within(values, seq)
        size = torch.bincount(seq, minlength=len(self.batch.sequences))
        keep[rank < torch.maximum((size + 1) // 2, torch.tensor(self.cfg.keep_per_sequence))[seq]] = True
        index = [k.nonzero().squeeze(1) for k in torch.split(keep, [g.size for g in self.batch.groups])]
        self._select_rows(index)
        return index

    def _select_rows(self, index: list[torch.Tensor]) -> None:
        self.batch.groups = [g.select(i) for g, i in zip(self.batch.groups, index)]
        if self.frozen is not None:
            self.frozen = FrozenMatching([r[i] for r, i in zip(self.frozen.rows, index)],
                                         [c[i] for c, i in zip(self.frozen.cols, index)])

    def _store(self, lat: list[torch.Tensor]) -> None:
        for g, x in zip(self.batch.groups, lat):
            g.latents = x.detach()

    # -- no gradient: cross-entropy method ------------------------------------------------------------
    def _cem(self) -> list[torch.Tensor]:
        """Elitist CEM: one Gaussian per (sequence, attention structure); its elites stay, the rest are redrawn."""
        lat = self._clamp(self.batch.latents())
        clusters = []
        for g in self.batch.groups:
            key = torch.cat([g.seq[:, None], *g.inputs], 1)
            clusters.append(torch.unique(key, dim=0, return_inverse=True)[1])
        scores: list[torch.Tensor] = []
        for it in range(self.cfg.iterations + 1):
            _, scores = self._objective(lat, grad=False)
            self._report(it, self.cfg.iterations, scores)
            if it == self.cfg.iterations:
                break
            new = []
            for x, r, cl in zip(lat, self._log_score, clusters):
                new.append(self._cem_step(x, r, cl))
            lat = self._clamp(new)
        self._store(lat)
        return scores

    def _cem_step(self, x: torch.Tensor, obj: torch.Tensor, cluster: torch.Tensor) -> torch.Tensor:
        b = x.shape[0]
        n_cl = int(cluster.max()) + 1
        size = torch.bincount(cluster, minlength=n_cl)
        n_elite = (size.double() * self.elite_fraction).ceil().long().clamp(min=1)
        elite = _rank_within(obj, cluster) < n_elite[cluster]
        w = elite.to(x.dtype)[:, None, None]
        count = n_elite.to(x.dtype)[:, None, None]
        mean = torch.zeros((n_cl, *x.shape[1:]), dtype=x.dtype).index_add_(0, cluster, x * w) / count
        dev = (x - mean[cluster]) ** 2 * w
        var = torch.zeros_like(mean).index_add_(0, cluster, dev) / (count - 1).clamp(min=1)
        std = var.sqrt().clamp(min=self.min_std)
        noise = torch.randn(x.shape, generator=self.gen, dtype=x.dtype)
        drawn = mean[cluster] + std[cluster] * noise  # clamped into the entities' boxes by the caller
        return torch.where(elite[:, None, None], x, drawn) if b else x


def _rank_within(values: torch.Tensor, labels: torch.Tensor) -> torch.Tensor:
    """``(B,)`` rank of each value among those with its label (0 = largest; ties by position)."""
    order = torch.argsort(-values, stable=True)
    order = order[torch.argsort(labels[order], stable=True)]
    counts = torch.bincount(labels, minlength=int(labels.max()) + 1 if labels.numel() else 0)
    starts = torch.cumsum(counts, 0) - counts
    rank = torch.empty_like(labels)
    rank[order] = torch.arange(labels.shape[0]) - starts[labels[order]]
    return rank


def _select(batch: CandidateBatch, scores: list[torch.Tensor], top_k: int) -> SearchResult:
    flat = torch.cat(scores)
    seq = torch.cat([g.seq for g in batch.groups])
    best = int(torch.argmax(flat))  # first maximum: deterministic
    sizes = [g.size for g in batch.groups]
    group = next(i for i, c in enumerate(torch.tensor(sizes).cumsum(0).tolist()) if best < c)
    row = best - sum(sizes[:group])
    skeleton, attention, subgoals = batch.candidate(group, row)
    starts = torch.tensor(sizes).cumsum(0) - torch.tensor(sizes)
    per_sequence: list[dict[str, Any]] = []
    best_of: list[tuple[tuple[str, ...], list[tuple[int, ...]], list[torch.Tensor], float] | None] = []
    for si, s in enumerate(batch.sequences):
        mask = seq == si
        mine = flat[mask]
        top = mine.topk(min(top_k, mine.numel())).values.tolist() if mine.numel() else []
        per_sequence.append({"skills": list(s), "score": top[0] if top else 0.0, "top_scores": top, "samples": int(mine.numel())})
        if not mine.numel():
            best_of.append(None)
            continue
        index = int(mask.nonzero()[int(torch.argmax(mine))])  # first maximum within the sequence
        g = int((index >= starts).sum()) - 1
        best_of.append((*batch.candidate(g, index - int(starts[g])), float(flat[index])))
    return SearchResult(skeleton, attention, subgoals, float(flat[best]), per_sequence, 0, 0, best=best_of)
