"""Batched candidate plans and their evaluation: all samples of all skill sequences in a few tensor ops.

A *candidate* is one skill sequence with one attention structure (sampled once, never optimised) and
one latent per produced entity. Candidates whose sequences share a cardinality signature
``((N_1, M_1), ..., (N_H, M_H))`` share every set size along the way, so they form one :class:`Group`
whose states are plain ``(B, K_h, D)`` tensors. Within a group the set after step ``h`` is
``[new (B, M_h, D), untouched (B, K_h - N_h, D)]`` (the convention of :mod:`pasta.core.plan`).

Feasibility is grouped by skill: every (sample, step) pair that uses skill ``k``, over all groups and
steps, is gathered and fed to skill ``k``'s feasibility in one call, so an evaluation makes one call per
skill plus one (or two) cost-model calls, whatever the number of samples, sequences or steps.
"""

from __future__ import annotations

import zlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import torch

from pasta.core import CostModel, Encoder, Skill
from pasta.core.errors import InputError
from pasta.core.matching import min_cost_matching
from pasta.planning.attention import signature_structures
from pasta.planning.config import ATTENTION_MODES
from pasta.planning.clearance import Clearance


@dataclass
class Group:
    """Samples whose skill sequences share one cardinality signature.

    Attributes:
        signature: ``((N_h, M_h), ...)`` per step, length ``H``.
        seq: ``(B,)`` index of each sample's skill sequence (into :attr:`CandidateBatch.sequences`).
        inputs: per step ``h``, ``(B, N_h)`` indices (sorted) of the consumed entities.
        kept: per step ``h``, ``(B, K_h - N_h)`` indices (sorted) of the untouched entities.
        latents: ``(B, sum_h M_h, D)`` the produced entities of all steps, step after step.
        fixed_pos: ``(B, F)`` where each fixed entity (:attr:`CandidateBatch.fixed`) ends in the final set.
        t_low, t_high: ``(B, sum_h M_h, 3)`` the centroid box of every produced entity, that of its step's
            skill (:func:`centroid_box`); ``None``: the encoder's box for all (no skill records its own).
    """

    signature: tuple[tuple[int, int], ...]
    seq: torch.Tensor
    inputs: list[torch.Tensor]
    kept: list[torch.Tensor]
    latents: torch.Tensor
    fixed_pos: torch.Tensor | None = None
    t_low: torch.Tensor | None = None
    t_high: torch.Tensor | None = None

    def clamp(self, latents: torch.Tensor, encoder: Encoder) -> torch.Tensor:
        """``latents (B, sum_h M_h, D)`` with every centroid clamped into its entity's box (a copy)."""
        if self.t_low is None or self.t_high is None:  # (set together)
            return encoder.clamp(latents)
        return clamp_centroids(latents, self.t_low, self.t_high, encoder.z_dim)

    @property
    def size(self) -> int:
        return int(self.seq.shape[0])

    @property
    def horizon(self) -> int:
        return len(self.signature)

    @property
    def offsets(self) -> list[int]:
        out, off = [], 0
        for _, m in self.signature:
            out.append(off)
            off += m
        return out

    def select(self, index: torch.Tensor, latents: torch.Tensor | None = None) -> Group:
        """The samples at ``index (B',)``; ``latents`` replaces the (already selected) latents if given."""
        return Group(
            self.signature,
            self.seq[index],
            [i[index] for i in self.inputs],
            [k[index] for k in self.kept],
            self.latents[index] if latents is None else latents,
            None if self.fixed_pos is None else self.fixed_pos[index],
            None if self.t_low is None else self.t_low[index],
            None if self.t_high is None else self.t_high[index],
        )


@dataclass
class CandidateBatch:
    """Every sample of every skill sequence of one search.

    Attributes:
        start: ``(K_0, D)`` the set the sequences start from.
        goal: ``(G, D)`` the goal set.
        sequences: the skill sequences (names).
        skill_ids: per sequence, the index of each step's skill in :attr:`skill_names`.
        skill_names: the skills the sequences use, in first-use order.
        groups: samples grouped by cardinality signature.
        fixed: pairs ``(start row, goal index)`` of entities already at their goal entity: never attended,
            matched to that goal entity in the set cost (:class:`pasta.core.PlanningProblem`, ``fixed``).
    """

    start: torch.Tensor
    goal: torch.Tensor
    sequences: list[tuple[str, ...]]
    skill_names: list[str]
    groups: list[Group]
    skill_ids: list[tuple[int, ...]] = field(default_factory=list)
    fixed: tuple[tuple[int, int], ...] = ()

    def __post_init__(self) -> None:
        if not self.skill_ids:
            self.skill_ids = [tuple(self.skill_names.index(n) for n in s) for s in self.sequences]

    @property
    def size(self) -> int:
        return sum(g.size for g in self.groups)

    def latents(self) -> list[torch.Tensor]:
        return [g.latents for g in self.groups]

    def candidate(self, group: int, row: int) -> tuple[tuple[str, ...], list[tuple[int, ...]], list[torch.Tensor]]:
        """One sample as ``(skeleton, attention per step, subgoals (M_h, D) per step)``."""
        g = self.groups[group]
        skeleton = self.sequences[int(g.seq[row])]
        attention = [tuple(int(i) for i in inp[row]) for inp in g.inputs]
        subgoals = [g.latents[row, off : off + m].detach().clone() for off, (_, m) in zip(g.offsets, g.signature)]
        return skeleton, attention, subgoals


def signature_of(sequence: Sequence[str], skills: Mapping[str, Skill]) -> tuple[tuple[int, int], ...]:
    return tuple((skills[n].n_in, skills[n].n_out) for n in sequence)


def encoder_box(encoder: Encoder) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """``(low, high)``: the encoder's box of training centroids, as floats."""
    return tuple(float(v) for v in encoder.t_low), tuple(float(v) for v in encoder.t_high)


def centroid_box(encoder: Encoder, skill: Skill) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """``(low, high)`` box of the centroids of ``skill``'s sub-goals. Without a box of the skill's own
    (:attr:`pasta.core.Skill.output_box`: where the entities it produced in its feasibility network's
    training data lay) it is the encoder's box of training centroids. With one, the height (y, up) is the
    skill's own: a piece rests on the surface the skill leaves it on (the lift's on the raised board, at
    y 0.086-0.114, above all of the encoder's floor pieces, up to 0.066; and outside its own heights the
    lift's network extrapolates badly: it rated a piece "set down" under the board above a real lift,
    f 0.935 against 0.827). On the table plane (x, z) it is the union of both: demonstrations place
    pieces in a region (the roll's lie in the spreading area, x 0.20-0.41) while tasks put them anywhere
    the encoder has seen (a crs goal rolls its piece at x 0.52)."""
    low, high = encoder_box(encoder)
    own = skill.output_box
    if own is None:
        return low, high
    return ((min(low[0], own[0][0]), float(own[0][1]), min(low[2], own[0][2])),
            (max(high[0], own[1][0]), float(own[1][1]), max(high[2], own[1][2])))


def training_boxes(encoder: Encoder, skills: Sequence[Skill]) -> list[tuple[tuple[float, ...], tuple[float, ...]]]:
    """The encoder's centroid box and each skill's own (:func:`centroid_box`), without repeats: where the
    models have seen pieces, hence where an observed or goal piece may lie (inside any one of them)."""
    boxes = [encoder_box(encoder)]
    for skill in skills:
        box = centroid_box(encoder, skill)
        if box not in boxes:
            boxes.append(box)
    return boxes


def clamp_to_skill(latents: torch.Tensor, encoder: Encoder, skill: Skill) -> torch.Tensor:
    """``latents (..., D)`` produced by a step of ``skill`` with ``t`` clamped into :func:`centroid_box`."""
    if skill.output_box is None:
        return encoder.clamp(latents)
    low, high = (torch.tensor(b, dtype=latents.dtype, device=latents.device) for b in centroid_box(encoder, skill))
    return clamp_centroids(latents, low, high, encoder.z_dim)


def clamp_centroids(latents: torch.Tensor, low: torch.Tensor, high: torch.Tensor, z_dim: int) -> torch.Tensor:
    """``latents (..., D)`` with ``t = latents[..., z_dim:]`` clamped into ``[low, high]`` (broadcast; a copy)."""
    t = torch.maximum(torch.minimum(latents[..., z_dim:], high.to(latents)), low.to(latents))
    return torch.cat([latents[..., :z_dim], t], -1)


def _slot_boxes(sequence: Sequence[str], skills: Mapping[str, Skill], encoder: Encoder) -> tuple[torch.Tensor, torch.Tensor]:
    """``(sum_h M_h, 3)`` low and high centroid bounds of every entity ``sequence`` produces, step after step."""
    low, high = [], []
    for name in sequence:
        lo, hi = centroid_box(encoder, skills[name])
        low += [lo] * skills[name].n_out
        high += [hi] * skills[name].n_out
    return torch.tensor(low, dtype=torch.float64), torch.tensor(high, dtype=torch.float64)


def sequence_stream(seed: int, sequence: Sequence[str]) -> torch.Generator:
    """A generator for ``sequence``'s draws alone: seeded by ``seed`` and the skill names (CRC-32, stable
    across processes and Python versions, unlike ``hash``)."""
    key = zlib.crc32("\x1f".join(sequence).encode(), zlib.crc32(str(int(seed)).encode()))
    return torch.Generator().manual_seed(key)


def sample_candidates(
    start: torch.Tensor,
    goal: torch.Tensor,
    sequences: Sequence[Sequence[str]],
    skills: Mapping[str, Skill],
    encoder: Encoder,
    num_samples: int,
    generator: torch.Generator,
    fixed: Sequence[tuple[int, int]] = (),
    attention: str = "sample",
    sequence_seed: int | None = None,
) -> CandidateBatch:
    """Draw ``num_samples`` candidates per sequence: random attention per sample and step, prior latents.

    Draw order (hence the result for a seed) is fixed: sequence after sequence, for each the attention of
    every step and then the latents. Without ``fixed`` entities the draws are what they were before
    ``fixed`` existed (same plans for the same seed).

    Args:
        start: ``(K_0, D)`` the set to start from.
        goal: ``(G, D)``.
        sequences: skill-name sequences; each must have enough entities to consume at every step (not
            counting the fixed ones: :func:`free_feasible`).
        fixed: pairs ``(start row, goal index)``: those start entities are never attended, so the attention
            is drawn among the other ``K_h - F`` entities only, whatever the number of fixed ones.
        attention: ``"sample"`` (the default above) or ``"enumerate"``: every attention structure of each
            sequence (:func:`pasta.planning.attention.attention_structures`, fixed entities never attended),
            ``num_samples`` latent draws for each, so a sequence has ``num_samples x structures`` candidates
            (the paper's "no sampling" ablation: one initialisation per structure, ``num_samples = 1``).
        sequence_seed: when given, each sequence draws from its own stream seeded by ``sequence_seed`` and
            the sequence's skill names (:func:`sequence_stream`) instead of ``generator``, so a sequence's
            candidates are the same whichever other sequences are drawn with it.
    """
    if attention not in ATTENTION_MODES:
        raise InputError(f"attention must be one of {ATTENTION_MODES}, got {attention!r}")
    if num_samples < 1:
        raise InputError(f"num_samples must be >= 1, got {num_samples}")
    if not sequences:
        raise InputError("no skill sequence to search")
    seqs = [tuple(s) for s in sequences]
    names: list[str] = []
    for s in seqs:
        names.extend(n for n in s if n not in names)
    dim = start.shape[-1]
    # per-entity centroid boxes only when some skill records its own (otherwise the encoder's, as always)
    own_boxes = any(skills[n].output_box is not None for n in names)
    fixed = tuple((int(i), int(j)) for i, j in fixed)
    n_fixed = len(fixed)
    parts: dict[tuple[tuple[int, int], ...], list[tuple]] = {}
    for si, seq in enumerate(seqs):
        sig = signature_of(seq, skills)
        k = start.shape[0]
        for n, m in sig:  # the set sizes are the same for every sample: check them up front
            if k - n_fixed < n:
                extra = f" ({n_fixed} of them fixed)" if n_fixed else ""
                raise InputError(f"sequence {list(seq)} consumes {n} entities from a set of {k}{extra}")
            k += m - n
        k = start.shape[0]
        count = num_samples
        draw = generator if sequence_seed is None else sequence_stream(sequence_seed, seq)
        if attention == "enumerate":
            chosen = _enumerate_structures(sig, k, [i for i, _ in fixed])
            count = num_samples * len(chosen[0])
            chosen = [c.repeat_interleave(num_samples, dim=0) for c in chosen]
        inputs, kept = [], []
        pos = torch.tensor([i for i, _ in fixed], dtype=torch.long).expand(count, -1).contiguous()  # (B, F)
        for h, (n, m) in enumerate(sig):
            if attention == "enumerate":  # the chosen entities sort first, then the rest (fixed ones among them)
                key = 1.0 + torch.zeros(count, k).scatter_(1, chosen[h], -1.0)
            else:
                key = torch.rand(count, k, generator=draw)
            if n_fixed:  # fixed entities sort last: never among the n consumed
                key = key + 2.0 * torch.zeros(count, k).scatter_(1, pos, 1.0)
            perm = key.argsort(dim=1)
            inputs.append(perm[:, :n].sort(dim=1).values)
            kept.append(perm[:, n:].sort(dim=1).values)
            if n_fixed:  # the next set is [new (m), kept...]: a kept entity moves to m + its rank among the kept
                pos = m + torch.searchsorted(kept[-1], pos)
            k += m - n
        total = sum(m for _, m in sig)
        lat = encoder.sample_prior(count * total, draw).to(start.dtype).reshape(count, total, dim)
        box: tuple[torch.Tensor, torch.Tensor] | tuple[None, None]
        if own_boxes:  # centroids drawn in the encoder's box, mapped into each slot's box (same where they agree)
            low, high = (b.to(start.dtype).expand(count, -1, -1) for b in _slot_boxes(seq, skills, encoder))
            e_low, e_high = (torch.tensor(b, dtype=start.dtype) for b in (encoder.t_low, encoder.t_high))
            z = encoder.z_dim
            t = lat[..., z:]
            mapped = low + (t - e_low) / (e_high - e_low).clamp(min=1e-12) * (high - low)
            same = (low == e_low) & (high == e_high)
            lat = clamp_centroids(torch.cat([lat[..., :z], torch.where(same, t, mapped)], -1), low, high, z)
            box = (low, high)
        else:
            lat, box = encoder.clamp(lat), (None, None)
        parts.setdefault(sig, []).append((si, inputs, kept, lat, pos, box))
    groups = []
    for sig, items in parts.items():
        groups.append(
            Group(
                sig,
                torch.cat([torch.full((it[3].shape[0],), it[0], dtype=torch.long) for it in items]),
                [torch.cat([it[1][h] for it in items]) for h in range(len(sig))],
                [torch.cat([it[2][h] for it in items]) for h in range(len(sig))],
                torch.cat([it[3] for it in items]),
                torch.cat([it[4] for it in items]) if n_fixed else None,
                torch.cat([it[5][0] for it in items]) if own_boxes else None,
                torch.cat([it[5][1] for it in items]) if own_boxes else None,
            )
        )
    return CandidateBatch(start, goal, seqs, names, groups, fixed=fixed)


def _enumerate_structures(signature, start_size: int, fixed_rows: Sequence[int]) -> list[torch.Tensor]:
    """:func:`pasta.planning.attention.signature_structures` as per step ``h`` an ``(S, N_h)`` index tensor."""
    rows = signature_structures(signature, start_size, fixed_rows)
    return [torch.tensor([steps[h] for steps in rows], dtype=torch.long).reshape(len(rows), n)
            for h, (n, _) in enumerate(signature)]


def free_feasible(sequence: Sequence[str], skills: Mapping[str, Skill], start_size: int, num_fixed: int) -> bool:
    """Whether ``sequence`` can run on the ``start_size - num_fixed`` entities that are not fixed."""
    k = start_size - num_fixed
    for n, m in signature_of(sequence, skills):
        if k < n:
            return False
        k += m - n
    return True


@dataclass
class FrozenMatching:
    """Per group, the matched final-entity and goal-entity indices ``(B, min(K_H, G))`` each."""

    rows: list[torch.Tensor]
    cols: list[torch.Tensor]

    def select(self, group: int, index: torch.Tensor) -> None:
        self.rows[group] = self.rows[group][index]
        self.cols[group] = self.cols[group][index]


@dataclass
class Evaluation:
    """Per group: ``log_feasibility (B, H)``, ``cost (B,)``, final states ``(B, K_H, D)``, the clearance
    ``penalty (B,)`` (zeros unless asked for); the matching used."""

    log_feasibility: list[torch.Tensor]
    cost: list[torch.Tensor]
    finals: list[torch.Tensor]
    matching: FrozenMatching
    penalty: list[torch.Tensor] = field(default_factory=list)

    @property
    def feasibility(self) -> list[torch.Tensor]:
        """Per group, ``(B, H)`` feasibility in ``[0, 1]``."""
        return [x.exp() for x in self.log_feasibility]


def _take(state: torch.Tensor, index: torch.Tensor) -> torch.Tensor:
    """``state (B, K, D)`` rows ``index (B, N)`` -> ``(B, N, D)``."""
    return state.gather(1, index[:, :, None].expand(-1, -1, state.shape[-1]))


def roll_states(batch: CandidateBatch, latents: Sequence[torch.Tensor], clearance: Clearance | None = None):
    """Per group, the consumed/produced tuples of every step, the final state and the clearance penalty.

    Returns:
        ``(tuples, finals, penalties)``: ``tuples[g][h] = (u_in (B, N_h, D), u_out (B, M_h, D))``,
        ``finals[g]`` ``(B, K_H, D)`` and ``penalties[g]`` ``(B,)`` summed over the steps
        (:mod:`pasta.planning.clearance`; zeros without ``clearance``).
    """
    tuples, finals, penalties = [], [], []
    widths = clearance.sweep_widths(batch.sequences) if clearance is not None else None
    for grp, lat in zip(batch.groups, latents):
        b = lat.shape[0]
        state = batch.start.unsqueeze(0).expand(b, -1, -1)
        penalty = lat.new_zeros(b)
        ext = clearance.start_extent.to(lat.dtype).unsqueeze(0).expand(b, -1, -1) if clearance is not None else None
        steps = []
        for h, (off, (_, m)) in enumerate(zip(grp.offsets, grp.signature)):
            new = lat[:, off : off + m]
            u_in = _take(state, grp.inputs[h])
            steps.append((u_in, new))
            if clearance is not None:
                assert ext is not None and widths is not None  # set with clearance
                p, ext = clearance.step_penalty(u_in, _take(ext, grp.inputs[h]), new, _take(state, grp.kept[h]),
                                                _take(ext, grp.kept[h]), widths[grp.seq, h])
                penalty = penalty + p
            state = torch.cat([new, _take(state, grp.kept[h])], 1)
        tuples.append(steps)
        finals.append(state)
        penalties.append(penalty)
    return tuples, finals, penalties


def evaluate(
    batch: CandidateBatch,
    latents: Sequence[torch.Tensor],
    skills: Mapping[str, Skill],
    cost_model: CostModel,
    *,
    frozen: FrozenMatching | None = None,
    clearance: Clearance | None = None,
) -> Evaluation:
    """Log-feasibility of every step and the final set cost of every sample, batched.

    Args:
        batch: the candidates (their attention; their own latents are ignored).
        latents: per group, ``(B_g, sum_h M_h, D)`` sub-goal latents (already clamped).
        frozen: evaluate the cost only on these matched pairs; ``None`` solves the matching.
        clearance: also score moving pieces through others (:mod:`pasta.planning.clearance`).

    The set cost matches ``min(K_H, G)`` pairs: every final entity to a distinct goal entity when
    ``K_H <= G``, every goal entity to a distinct final entity otherwise (partial windows of the
    receding-horizon planner may end with a set size other than the goal's).
    """
    tuples, finals, penalties = roll_states(batch, latents, clearance)
    # -- feasibility: one call per skill over every (group, step, sample) that uses it ---------------
    longest = max(len(s) for s in batch.skill_ids)
    seq_skill = torch.tensor([list(s) + [-1] * (longest - len(s)) for s in batch.skill_ids], dtype=torch.long)
    calls: dict[int, list[tuple[int, int, torch.Tensor | None]]] = {}
    for g, grp in enumerate(batch.groups):
        ids = seq_skill[grp.seq]  # (B, H)
        for h in range(grp.horizon):
            col = ids[:, h]
            used = torch.unique(col).tolist()
            for k in used:
                idx = None if len(used) == 1 else (col == k).nonzero().squeeze(1)
                calls.setdefault(k, []).append((g, h, idx))
    pieces: dict[tuple[int, int], list[tuple[torch.Tensor | None, torch.Tensor]]] = {}
    for k in sorted(calls):
        u_in, u_out, sizes = [], [], []
        for g, h, idx in calls[k]:
            a, b = tuples[g][h]
            if idx is not None:
                a, b = a[idx], b[idx]
            u_in.append(a)
            u_out.append(b)
            sizes.append(a.shape[0])
        f = skills[batch.skill_names[k]].log_feasibility(torch.cat(u_in), torch.cat(u_out))
        for (g, h, idx), part in zip(calls[k], torch.split(f, sizes)):
            pieces.setdefault((g, h), []).append((idx, part))
    feas = []
    for g, grp in enumerate(batch.groups):
        cols = []
        for h in range(grp.horizon):
            ps = pieces[(g, h)]
            if len(ps) == 1:
                cols.append(ps[0][1])
            else:
                order = torch.cat([i for i, _ in ps if i is not None])  # (all are: several calls have an index)
                cols.append(torch.cat([p for _, p in ps])[order.argsort()])
        feas.append(torch.stack(cols, 1))
    cost, matching = set_costs(batch, finals, cost_model, frozen=frozen)
    return Evaluation(feas, cost, finals, matching, penalties)


def set_costs(
    batch: CandidateBatch,
    finals: Sequence[torch.Tensor],
    cost_model: CostModel,
    *,
    frozen: FrozenMatching | None = None,
) -> tuple[list[torch.Tensor], FrozenMatching]:
    """Per group, ``(B,)`` cost of the final sets against the goal (see :func:`evaluate`), and the matching used.

    With fixed entities (:attr:`CandidateBatch.fixed`) each is matched to its own goal entity and only the
    other entities are matched by cost (:func:`fixed_matching`).
    """
    g_goal = batch.goal.shape[0]
    if frozen is None and batch.fixed:
        fixed_rows, fixed_cols = [], []
        for grp, f in zip(batch.groups, finals):
            assert grp.fixed_pos is not None  # every group has it when the batch has fixed entities
            r, c = fixed_matching(f, batch.goal, grp.fixed_pos, [j for _, j in batch.fixed], cost_model)
            fixed_rows.append(r)
            fixed_cols.append(c)
        return set_costs(batch, finals, cost_model, frozen=FrozenMatching(fixed_rows, fixed_cols))
    if frozen is not None:  # only the matched pairs, all groups in one call
        a = [_take(f, r) for f, r in zip(finals, frozen.rows)]
        b = [batch.goal[c] for c in frozen.cols]
        pairs = [x.shape[0] * x.shape[1] for x in a]
        flat_a = torch.cat([x.reshape(-1, 1, x.shape[-1]) for x in a])
        flat_b = torch.cat([x.reshape(-1, 1, x.shape[-1]) for x in b])
        c = cost_model.pairwise(flat_a, flat_b).reshape(-1)
        return [part.reshape(x.shape[0], x.shape[1]).sum(1) for part, x in zip(torch.split(c, pairs), a)], frozen
    n = len(finals)
    out: list = [None] * n
    rows: list = [None] * n
    cols: list = [None] * n
    by_k: dict[int, list[int]] = {}
    for g, f in enumerate(finals):
        by_k.setdefault(f.shape[1], []).append(g)
    for k, gs in by_k.items():
        fin = torch.cat([finals[g] for g in gs])
        c = cost_model.pairwise(fin, batch.goal.unsqueeze(0).expand(fin.shape[0], -1, -1))  # (B, K, G)
        total, assign = min_cost_matching(c if k <= g_goal else c.transpose(1, 2))
        sizes = [finals[g].shape[0] for g in gs]
        for g, part, matched in zip(gs, torch.split(total, sizes), torch.split(assign, sizes)):
            out[g] = part
            ident = torch.arange(matched.shape[1]).expand(matched.shape[0], -1).contiguous()
            rows[g], cols[g] = (ident, matched) if k <= g_goal else (matched, ident)
    return out, FrozenMatching(rows, cols)


def fixed_matching(final: torch.Tensor, goal: torch.Tensor, fixed_pos: torch.Tensor, fixed_goal: Sequence[int],
                   cost_model: CostModel) -> tuple[torch.Tensor, torch.Tensor]:
    """The set-cost matching when some final entities are known to be some goal entities.

    Args:
        final: ``(B, K, D)`` final sets; goal: ``(G, D)``.
        fixed_pos: ``(B, F)`` positions in ``final`` of the fixed entities; fixed_goal: their ``F`` goal indices.

    Returns:
        ``(rows, cols)``, each ``(B, min(K, G))``: the fixed pairs, plus the minimum-cost matching
        (:func:`pasta.core.matching.min_cost_matching`, on the cost model's pairwise costs) of the
        ``K - F`` other final entities to the ``G - F`` other goal entities. The cost model is not asked
        about any pair that involves a fixed entity, so the matching work does not grow with ``F``.
    """
    b, k, _ = final.shape
    f = len(fixed_goal)
    taken = torch.zeros(b, k, dtype=torch.long).scatter_(1, fixed_pos, 1)
    free_pos = torch.argsort(taken, dim=1, stable=True)[:, : k - f]  # (B, K - F), ascending
    gset = {int(j) for j in fixed_goal}
    free_goal = torch.tensor([j for j in range(goal.shape[0]) if j not in gset], dtype=torch.long)
    kf, gf = k - f, free_goal.shape[0]
    with torch.no_grad():
        if kf == 0 or gf == 0:
            c = final.new_zeros(b, kf, gf)
        else:
            c = cost_model.pairwise(_take(final, free_pos), goal[free_goal].unsqueeze(0).expand(b, -1, -1))  # (B, kf, gf)
        if kf <= gf:
            _, assign = min_cost_matching(c)
            rows, cols = free_pos, free_goal[assign]
        else:
            _, assign = min_cost_matching(c.transpose(1, 2))
            rows, cols = free_pos.gather(1, assign), free_goal.expand(b, -1)
    fixed_cols = torch.tensor([int(j) for j in fixed_goal], dtype=torch.long).expand(b, -1)
    return torch.cat([rows, fixed_pos], 1), torch.cat([cols, fixed_cols], 1)
