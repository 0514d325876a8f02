"""Training of one skill's :class:`~pasta.nn.feasibility.SetFeasibility`.

- Positives: a state and a later state of the same demonstration of the skill, after removing the
  entities unchanged between them (Chamfer < ``unchanged_threshold``); kept when exactly ``N_k`` inputs
  and ``M_k`` outputs remain. Training adds Gaussian noise to ``z`` (``z_noise``) and ``t`` (``t_noise``).
- Hard negatives: ``hard_per_positive`` copies of each positive with one slot replaced by a prior sample.
- Random negatives: every slot a prior sample (as many tuples as positives in the batch).
- Loss: binary cross-entropy, weighted 0.5 (positives) / 0.25 (hard) / 0.25 (random).

Flat 3D (``flat=true``): the same with ``N = M = 1`` and the whole scene as the entity; the positive
of a demonstration is (its first step, the dough after the skill), see
:func:`pasta.train.latents.encode_scenes`.
"""

from __future__ import annotations

import functools
from dataclasses import asdict, dataclass
from typing import Any, cast

import numpy as np
import torch
import torch.nn.functional as F

from pasta.core.errors import ConfigError, InputError
from pasta.nn.feasibility import SetFeasibility
from pasta.nn.loading import FEASIBILITY_MODULE
from pasta.train.latents import EncodedDemo, changed_entities

WEIGHTS = (0.5, 0.25, 0.25)
# hard negatives per held-out positive for val_auc_hard when training uses none (hard_per_positive=0)
MEASURED_HARD = 10


@dataclass
class FeasibilityTrainConfig:
    """Feasibility settings (``key=value`` on ``pasta train feasibility``).

    Attributes:
        skill: the skill whose demonstrations are the positives (required).
        hidden: network width.
        hard_per_positive: hard negatives per positive (0: none, the paper's "no hard negatives" ablation;
            random negatives only, held-out hard negatives still measured).
        shift_per_positive: near-miss negatives per positive: the tuple with its produced entities
            moved together by ``shift_min``..``shift_max`` in the table plane (x, z). Right for skills
            that cannot carry dough far (roll, cut): without them the network accepts an output a few
            centimetres from where the skill leaves it, and plans inherit that slack. 0 (default) for push.
        shift_min, shift_max: the displacement range of those negatives.
        shift_entities: which produced entities a near miss moves: ``all`` (default: all by one offset)
            or ``one`` (one of them, chosen uniformly; the rest stay). For skills with several outputs
            whose layout is fixed by the skill: the cut's two halves lie side by side, and a cut network
            trained with ``all`` near misses, or none, rated halves 37 cm apart f 0.997 (docs/learning.md).
        z_noise, t_noise: std of the Gaussian noise on ``z`` and ``t`` of positives (training only).
        unchanged_threshold: Chamfer below which an entity counts as unchanged.
        match_points: points per entity used for that Chamfer.
        max_pairs_per_demo: positives drawn per demonstration at most (seeded).
        num_points, stride, val_fraction: as for the VAE.
        vae: trained VAE directory (default ``OUT/vae``).
        flat: Flat 3D baseline: a ``1 -> 1`` network on whole-scene latents of the ``flat`` encoder
            (``OUT/vae`` must be a scene VAE); each demonstration gives one positive, (its first
            step, the dough after the skill), and ``stride`` / ``max_pairs_per_demo`` are unused.
    """

    skill: str = ""
    hidden: int = 256
    hard_per_positive: int = 10
    shift_per_positive: int = 0
    shift_min: float = 0.03
    shift_max: float = 0.1
    shift_entities: str = "all"
    z_noise: float = 0.02
    t_noise: float = 0.01
    unchanged_threshold: float = 5e-4
    match_points: int = 200
    max_pairs_per_demo: int = 200
    num_points: int = 1000
    stride: int = 1
    val_fraction: float = 0.2
    vae: str = ""
    flat: bool = False

    def __post_init__(self) -> None:
        from pasta.config.validate import check_choice, check_ranges
        from pasta.train.vae import MAX_POINTS

        check_ranges(self, {"hidden": (1, 1 << 16), "hard_per_positive": (0, 10_000), "shift_per_positive": (0, 10_000),
                            "shift_min": (0.0, None), "shift_max": (self.shift_min, None), "z_noise": (0.0, None),
                            "t_noise": (0.0, None), "unchanged_threshold": (0.0, None), "match_points": (1, MAX_POINTS),
                            "max_pairs_per_demo": (1, None), "num_points": (1, MAX_POINTS), "stride": (1, None),
                            "val_fraction": (0.0, 1.0, "[)")})
        check_choice(self.shift_entities, "shift_entities", ("all", "one"))


def train_dict(cfg: Any) -> dict[str, Any]:
    """The settings saved with the weights (``model.json``'s ``train``)."""
    return asdict(cfg)


def scope_config(cfg: Any) -> dict[str, str]:
    """``{"scope": "scene"}`` for a Flat 3D run, else ``{"scope": "entity"}`` (checked by the loaders, so an
    entity planner never loads a Flat 3D network, nor the reverse)."""
    return {"scope": "scene" if getattr(cfg, "flat", False) else "entity"}


def positive_tuples(
    demos: list[EncodedDemo], n_in: int, n_out: int, cfg: FeasibilityTrainConfig, *, seed: int = 0
) -> tuple[torch.Tensor, torch.Tensor]:
    """``(U_in (B, N, D), U_out (B, M, D))`` of every valid (state, later state) pair of ``demos``."""
    u_in, u_out = [], []
    for k, demo in enumerate(demos):
        steps = len(demo.latents)
        pairs = [(a, b) for a in range(steps) for b in range(a + 1, steps)]
        rng = np.random.default_rng([seed, k])
        if len(pairs) > cfg.max_pairs_per_demo:
            pairs = [pairs[i] for i in sorted(rng.choice(len(pairs), cfg.max_pairs_per_demo, replace=False))]
        for a, b in pairs:
            if len(demo.latents[a]) < n_in or len(demo.latents[b]) < n_out:
                continue
            ia, ib = changed_entities(demo.clouds[a], demo.clouds[b], threshold=cfg.unchanged_threshold, points=cfg.match_points)
            if len(ia) == n_in and len(ib) == n_out:
                u_in.append(demo.latents[a][ia])
                u_out.append(demo.latents[b][ib])
    if not u_in:
        return torch.empty(0, n_in, 0), torch.empty(0, n_out, 0)
    return torch.stack(u_in), torch.stack(u_out)


def hard_negatives(u_in: torch.Tensor, u_out: torch.Tensor, copies: int, prior: Any, generator: torch.Generator):
    """``copies`` versions of each tuple with one uniformly chosen slot replaced by a prior sample."""
    tuples = torch.cat([u_in, u_out], 1).repeat(copies, 1, 1)  # (B * copies, N + M, D)
    b, slots, _ = tuples.shape
    which = torch.randint(slots, (b,), generator=generator)
    tuples[torch.arange(b), which] = prior(b, generator)
    n = u_in.shape[1]
    return tuples[:, :n], tuples[:, n:]


def shifted_negatives(u_in: torch.Tensor, u_out: torch.Tensor, copies: int, z_dim: int, low: float, high: float,
                      generator: torch.Generator, entities: str = "all") -> tuple[torch.Tensor, torch.Tensor]:
    """``copies`` versions of each tuple whose produced entities move by one random offset of length in
    ``[low, high]`` in the table plane (centroid ``t = u[z_dim:z_dim+3]``, y is up): all of them
    (``entities="all"``) or one uniformly chosen (``"one"``, the same draws otherwise). (Offsets in any
    direction, for skills whose output height matters, did not fix the lift: docs/experiments.)"""
    if entities not in ("all", "one"):
        raise ConfigError(f"shift_entities must be 'all' or 'one', got {entities!r}")
    u_in, u_out = u_in.repeat(copies, 1, 1), u_out.repeat(copies, 1, 1).clone()
    b = u_out.shape[0]
    angle = torch.rand(b, generator=generator) * 2 * torch.pi
    direction = torch.stack([torch.cos(angle), torch.zeros(b), torch.sin(angle)], 1)
    length = low + torch.rand(b, generator=generator) * (high - low)
    offset = (length[:, None] * direction)[:, None, :].expand(-1, u_out.shape[1], -1)
    if entities == "one":  # (B, M, 1): only the chosen entity of each tuple moves
        which = torch.randint(u_out.shape[1], (b,), generator=generator)
        offset = offset * (torch.arange(u_out.shape[1])[None, :] == which[:, None]).to(offset.dtype)[..., None]
    u_out[:, :, z_dim:z_dim + 3] += offset
    return u_in, u_out


class FeasibilityTask:
    """:class:`pasta.train.loop.TrainTask` of one skill's feasibility."""

    module = FEASIBILITY_MODULE

    def __init__(self, skill: str, n_in: int, n_out: int, train: tuple, val: tuple, encoder: Any,
                 cfg: FeasibilityTrainConfig, *, seed: int = 0) -> None:
        if len(train[0]) == 0:
            raise InputError(f"no positive ({n_in} -> {n_out} entities) pairs in the training demonstrations of '{skill}'")
        self.skill, self.cfg, self.encoder = skill, cfg, encoder
        self.z_dim = encoder.z_dim
        torch.manual_seed(seed)
        self.model = SetFeasibility(n_in, n_out, encoder.latent_dim, cfg.hidden)
        self.train_in, self.train_out = train
        self.val_in, self.val_out = val if len(val[0]) else train
        gen = torch.Generator().manual_seed(seed + 1)
        # hard negatives are always measured (val_auc_hard; MEASURED_HARD copies when training uses none, the
        # paper's "no hard negatives" ablation), and in the validation loss only when training uses them
        plain = hard_negatives(self.val_in, self.val_out, cfg.hard_per_positive or MEASURED_HARD, self.prior, gen)
        # near misses, always measured (val_auc_shift), trained on only with shift_per_positive > 0
        self.val_shift = shifted_negatives(self.val_in, self.val_out, 2, self.z_dim, cfg.shift_min, cfg.shift_max, gen,
                                           cfg.shift_entities)
        self.val_hard = _cat(plain, self.val_shift) if cfg.shift_per_positive > 0 else plain
        trained = ([plain] if cfg.hard_per_positive > 0 else []) + ([self.val_shift] if cfg.shift_per_positive > 0 else [])
        self.val_hard_trained = functools.reduce(_cat, trained) if trained else None
        m = len(self.val_in)
        self.val_random = (self.prior(m * n_in, gen).view(m, n_in, -1), self.prior(m * n_out, gen).view(m, n_out, -1))
        # where the skill's produced entities lay (all positives): the planner's box for its sub-goals
        t_out = torch.cat([self.train_out, self.val_out])[..., self.z_dim:].reshape(-1, 3)
        self.output_box = [[float(v) for v in t_out.amin(0)], [float(v) for v in t_out.amax(0)]]

    def prior(self, n: int, generator: torch.Generator) -> torch.Tensor:
        return self.encoder.sample_prior(n, generator)

    def config(self) -> dict[str, Any]:
        return {**self.model.config(), "skill": self.skill, **scope_config(self.cfg), "train": train_dict(self.cfg),
                "output_box": self.output_box}

    def batches(self, batch_size: int, generator: torch.Generator):
        order = torch.randperm(len(self.train_in), generator=generator)
        for i in range(0, len(order), batch_size):
            yield order[i : i + batch_size]

    def _noisy(self, u: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
        std = torch.full((u.shape[-1],), self.cfg.t_noise)
        std[: self.z_dim] = self.cfg.z_noise
        return u + torch.randn(u.shape, generator=generator) * std

    def loss(self, batch: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
        u_in, u_out = self._noisy(self.train_in[batch], generator), self._noisy(self.train_out[batch], generator)
        hard = None
        if self.cfg.hard_per_positive > 0:
            hard = hard_negatives(u_in, u_out, self.cfg.hard_per_positive, self.prior, generator)
        if self.cfg.shift_per_positive > 0:
            near = shifted_negatives(u_in, u_out, self.cfg.shift_per_positive, self.z_dim, self.cfg.shift_min,
                                     self.cfg.shift_max, generator, self.cfg.shift_entities)
            hard = near if hard is None else _cat(hard, near)
        b, n, m = len(batch), u_in.shape[1], u_out.shape[1]
        rand = (self.prior(b * n, generator).view(b, n, -1), self.prior(b * m, generator).view(b, m, -1))
        return self._weighted((u_in, u_out), hard, rand)

    def _weighted(self, pos, hard, rand) -> torch.Tensor:
        """The weighted BCE of positives, hard (``None``: none trained on) and random negatives."""
        terms = []
        for pair, label, w in zip((pos, hard, rand), (1.0, 0.0, 0.0), WEIGHTS):
            if pair is None:
                continue
            a, b = pair
            logits = self.model.logits(a, b)
            terms.append(w * F.binary_cross_entropy_with_logits(logits, torch.full_like(logits, label)))
        return cast(torch.Tensor, sum(terms))  # (the positives are always there)

    @torch.no_grad()
    def validate(self) -> dict[str, float]:
        from sklearn.metrics import roc_auc_score

        pos = self.model(self.val_in, self.val_out).numpy()
        hard = self.model(*self.val_hard).numpy()
        rand = self.model(*self.val_random).numpy()
        shift = self.model(*self.val_shift).numpy()

        def auc(neg: np.ndarray) -> float:
            return float(roc_auc_score(np.r_[np.ones(len(pos)), np.zeros(len(neg))], np.r_[pos, neg]))

        return {
            "val_loss": float(self._weighted((self.val_in, self.val_out), self.val_hard_trained, self.val_random)),
            "val_auc_hard": auc(hard),
            "val_auc_random": auc(rand),
            "val_auc_shift": auc(shift),
        }


def _cat(a: tuple[torch.Tensor, torch.Tensor], b: tuple[torch.Tensor, torch.Tensor]) -> tuple[torch.Tensor, torch.Tensor]:
    return torch.cat([a[0], b[0]]), torch.cat([a[1], b[1]])
