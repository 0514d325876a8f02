"""Training of a skill's learned reset (start) pose (:mod:`pasta.policy.reset` holds the network and its loading).

The regressor learns, per demonstration, the tool's ``x`` offset from the initial dough centroid at the end
of the expert's align phase (:func:`align_offset`: the first step with a vertical action), or with
``target="skill"`` the skill's :meth:`~pasta.core.skill.Skill.reset_target` of that ``x``.

``pasta train reset data=DIR out=MODELS skill=NAME [key=value ...]`` (:func:`train_command`; keys of
:class:`~pasta.train.loop.LoopConfig` and :class:`ResetTrainConfig`) writes ``MODELS/policy/<skill>/reset.safetensors``
+ ``reset.json`` beside the policy's ``model.*``, ``reset_last.*`` to resume, and the held-out errors in
``reset_metrics.json``; the pipeline's ``reset`` stage runs the same (:func:`reset_command`).
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from pasta.core.decompose import decompose_labels
from pasta.core.errors import ConfigError
from pasta.core.files import write_json
from pasta.policy.reset import MODULE, NAME, ResetConfig, ResetPoseNet, left_piece_share, reset_inputs, x_at_share
from pasta.train.decoded import check_encoder_weights, decoded_pieces, goal_draw, load_encoder
from pasta.train.loop import LoopConfig, fit, numpy_rng, torch_threads

__all__ = ["LOOP_DEFAULTS", "ResetTask", "ResetTrainConfig", "align_offset", "reset_command",
           "reset_configs", "share_below", "train_command", "train_reset"]


def share_below(cloud: np.ndarray, x: float) -> float:
    """The share of ``cloud (P, 3)``'s points whose ``x`` lies below ``x`` (an ``x_share`` target)."""
    return float(np.mean(np.asarray(cloud, np.float64)[:, 0] < x))


def align_offset(demo: Any) -> tuple[float, int]:
    """The demo's tool ``x`` minus the initial dough centroid ``x`` at its first step with a vertical
    action component, and that step's index."""
    vertical = np.flatnonzero(np.abs(np.asarray(demo.action)[:, 1]) > 0)
    k = int(vertical[0]) if len(vertical) else 0
    return float(demo.tool_pose[k, 0] - np.asarray(demo.dough[0])[:, 0].mean()), k


def _dataset(demos: Sequence[Any], skill: Any = None, x_share: bool = False) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, int]]:
    """``(dough, goal, targets (R,), align steps)`` per demo: the tool's offset from the dough centroid
    ``x``, or with ``skill`` its ``reset_target`` of the tool ``x`` (the first value as an offset); with
    ``x_share`` the first value is instead the share of the dough's points below that ``x``."""
    out = []
    for d in demos:
        off, k = align_offset(d)
        dough = np.asarray(d.dough[0], np.float32)
        c = float(np.asarray(dough, np.float64)[:, 0].mean())
        y = np.array([off], np.float32)
        if skill is not None:
            y = np.asarray(skill.reset_target(c + off), np.float64)
            y[0] -= c
        if x_share:
            y[0] = share_below(dough, c + y[0])
        out.append((dough, np.asarray(d.after, np.float32), y.astype(np.float32), k))
    return out


def _batch(items: Sequence[tuple], n: int, rng: np.random.Generator, noise: float,
           decoded: Sequence[Any] | None = None, p_decoded: float = 0.0,
           piece_share: bool = False, share_prior: bool = False) -> tuple[torch.Tensor, torch.Tensor]:
    """Inputs and targets of ``items``; with ``share_prior`` the first target less the goal's
    :func:`left_piece_share` (of the goal as drawn: a decoded goal's pieces keep their shares)."""
    xs, ys = [], []
    for i, (dough, goal, off, _) in enumerate(items):
        if decoded is not None:
            goal = goal_draw(goal, decoded[i], p_decoded, rng)
        labels = decompose_labels(goal) if piece_share or share_prior else None
        pts, _ = reset_inputs(dough, goal, n, rng, piece_share, labels)
        if noise > 0:
            pts[:, :3] += rng.uniform(-noise, noise, pts[:, :3].shape).astype(np.float32)
        xs.append(pts)
        y = np.array(off, np.float64)
        if share_prior:
            y[0] -= left_piece_share(goal, labels)
        ys.append(y)
    return torch.as_tensor(np.stack(xs)), torch.as_tensor(np.stack(ys).astype(np.float32))


#: loop defaults of the reset-pose trainer (:class:`pasta.train.loop.LoopConfig`): the shipped regressor's
#: (docs/policies.md, "Learned reset pose for the cut"); the one place its epochs are set
LOOP_DEFAULTS: dict[str, Any] = {"epochs": 90, "batch_size": 32, "lr": 1e-3}


class ResetTask:
    """The reset-pose regressor as a :class:`pasta.train.loop.TrainTask`.

    Targets are the ``train`` demos' align offsets (:func:`align_offset`), or with ``cfg.target == "skill"``
    the offsets of ``skill.reset_target``; validation is the mean absolute error of the first regressed
    value on ``val`` (``train`` itself when empty), so the loop keeps the epoch with the lowest one.

    Args:
        cfg: the network's sizes and target (saved in ``reset.json``).
        seed: seed of the initialisation, the decoded goals and the fixed validation batch.
        noise: half-width of the uniform point noise on training samples.
        skill: the skill object (its name goes into the checkpoint; ``reset_target`` for ``"skill"``).
        encoder: a :class:`pasta.core.Encoder` for ``decoded_goals``.
        decoded_goals: probability that a training sample's goal piece is replaced by its ``encoder``
            reconstruction (:func:`decoded_pieces`), as a plan's decoded sub-goals are at execution.
        decoded_noise: std of Gaussian noise on the shape code of those reconstructions (4 per piece).
    """

    module = MODULE

    def __init__(self, train: Sequence[Any], val: Sequence[Any], cfg: ResetConfig, *, seed: int = 0,
                 noise: float = 0.002, skill: Any = None, encoder: Any = None, decoded_goals: float = 0.0,
                 decoded_noise: float = 0.0) -> None:
        if cfg.target not in ("tool", "skill"):
            raise ValueError(f"reset target must be 'tool' or 'skill', got {cfg.target!r}")
        if cfg.target == "skill" and skill is None:
            raise ValueError("reset target 'skill' needs the skill (its reset_target)")
        if decoded_goals > 0 and encoder is None:
            raise ValueError("decoded_goals needs the encoder that decodes the goal pieces")
        self.cfg, self.noise, self.decoded_goals = cfg, noise, decoded_goals
        self.skill_name = str(getattr(skill, "name", "") or "")
        self.own = skill if cfg.target == "skill" else None
        self.val_demos = list(val or train)
        self.train_items = _dataset(train, self.own, cfg.x_share)
        self.val_items = _dataset(self.val_demos, self.own, cfg.x_share)
        # held-out targets in metres, for the figures
        self.val_metres = _dataset(self.val_demos, self.own) if cfg.x_share else self.val_items
        if len(self.train_items[0][2]) != cfg.outputs:
            raise ValueError(f"the regressor has {cfg.outputs} outputs but the targets have "
                             f"{len(self.train_items[0][2])} values")
        rng = np.random.default_rng(seed)
        self.decoded = ([decoded_pieces(t[1], encoder, noise=decoded_noise, draws=4 if decoded_noise > 0 else 1, rng=rng)
                         for t in self.train_items] if decoded_goals > 0 else None)
        torch.manual_seed(seed)
        self.model = ResetPoseNet(cfg)
        self.val_x, self.val_y = _batch(self.val_items, cfg.points, np.random.default_rng(seed + 1), 0.0,
                                        piece_share=cfg.piece_share, share_prior=cfg.share_prior)
        # what a share_prior regressor's first output is added to (the held-out goals are never decoded)
        self.val_prior = np.array([left_piece_share(t[1]) if cfg.share_prior else 0.0 for t in self.val_items])

    def config(self) -> dict[str, Any]:
        return {"skill": self.skill_name, "network": asdict(self.cfg)}

    def batches(self, batch_size: int, generator: torch.Generator) -> Iterator[tuple[torch.Tensor, torch.Tensor]]:
        rng = numpy_rng(generator)
        order = rng.permutation(len(self.train_items))
        for i in range(0, len(order), batch_size):
            idx = order[i:i + batch_size]
            yield _batch([self.train_items[j] for j in idx], self.cfg.points, rng, self.noise,
                         None if self.decoded is None else [self.decoded[j] for j in idx], self.decoded_goals,
                         self.cfg.piece_share, self.cfg.share_prior)

    def loss(self, batch: tuple[torch.Tensor, torch.Tensor], generator: torch.Generator) -> torch.Tensor:
        x, y = batch
        units = self.model.units
        return nn.functional.smooth_l1_loss(self.model(x) / units, y / units, beta=0.05)

    @torch.no_grad()
    def validate(self) -> dict[str, float]:
        """``val_loss``: the held-out mean absolute error of the first value (metres, or a share)."""
        return {"val_loss": float((self.model(self.val_x) - self.val_y)[:, 0].abs().mean())}

    @torch.no_grad()
    def metrics(self) -> dict[str, Any]:
        """Held-out errors of the model as it is: in the regressed target and, for ``"skill"``, of the tool
        ``x`` the skill places from it; shares are turned into metres on each held-out dough."""
        self.model.eval()
        pred = self.model(self.val_x).numpy().astype(np.float64)
        vy = self.val_y.numpy().astype(np.float64)
        pred[:, 0] += self.val_prior
        vy[:, 0] += self.val_prior
        prior = self.val_prior.copy()  # the goal's split alone (share_prior), as a share
        if self.cfg.x_share:  # shares -> offsets in metres on each held-out dough
            for i, (dough, _, _, _) in enumerate(self.val_items):
                c = float(np.asarray(dough, np.float64)[:, 0].mean())
                pred[i, 0] = x_at_share(dough, pred[i, 0]) - c
                prior[i] = x_at_share(dough, prior[i]) - c
            vy = np.stack([t[2] for t in self.val_metres]).astype(np.float64)
        errs = np.abs(pred - vy)
        err = errs[:, 0]
        metrics: dict[str, Any] = {
            "target": self.cfg.target, "train_demos": len(self.train_items), "heldout_demos": len(self.val_items),
            "heldout_mae_m": float(err.mean()), "heldout_median_ae_m": float(np.median(err)),
            "heldout_max_ae_m": float(err.max()), "target_std_m": float(np.std([t[2][0] for t in self.val_metres])),
            "demo_align_steps_median": float(np.median([t[3] for t in self.train_items]))}
        if self.cfg.share_prior:  # what the network adds to the goal's split
            metrics["heldout_prior_mae_m"] = float(np.abs(prior - vy[:, 0]).mean())
        if self.cfg.outputs > 1:  # the unitless values (the cut: the knife's phase in its cell)
            metrics["heldout_mae_other"] = [float(v) for v in errs[:, 1:].mean(0)]
        if self.own is not None:  # what the tool does with it: the skill's tool x against the demos' own
            tool_err = []
            for (dough, _, _, _), d, p in zip(self.val_items, self.val_demos, pred):
                c = float(np.asarray(dough, np.float64)[:, 0].mean())
                x = self.own.reset_tool_x((c + float(p[0]), *(float(v) for v in p[1:])))
                tool_err.append(abs(x - (c + align_offset(d)[0])))
            metrics.update(heldout_tool_mae_m=float(np.mean(tool_err)),
                           heldout_tool_median_ae_m=float(np.median(tool_err)))
        return metrics


def train_reset(train: Sequence[Any], val: Sequence[Any], cfg: ResetConfig | None = None, *, out: str | Path,
                loop: LoopConfig | None = None, noise: float = 0.002, skill: Any = None, encoder: Any = None,
                decoded_goals: float = 0.0, decoded_noise: float = 0.0) -> tuple[ResetPoseNet, dict[str, Any]]:
    """Fit the regressor (:class:`ResetTask`) with the shared loop into ``out/reset.*`` (the best epoch by
    held-out error; ``out/reset_last.*`` to resume); returns the net and its held-out metrics.

    ``loop``: the loop's settings (default :data:`LOOP_DEFAULTS`); its ``seed`` also seeds the task.
    Held-out errors are on the demonstrations' own goals."""
    loop = loop or LoopConfig(**LOOP_DEFAULTS)
    task = ResetTask(train, val, cfg or ResetConfig(), seed=loop.seed, noise=noise, skill=skill, encoder=encoder,
                     decoded_goals=decoded_goals, decoded_noise=decoded_noise)
    result = fit(task, loop, out, name=NAME)
    return task.model, {**task.metrics(), "best_epoch": result.best_epoch}


@dataclass
class ResetTrainConfig:
    """Settings of :func:`reset_command` beside the loop's (:class:`pasta.train.loop.LoopConfig`; ``pasta train
    reset`` and the pipeline's ``reset`` stage). The defaults are the shipped regressor's (the cut's: 150 more
    long-cut demonstrations; held-out error 1.3 mm, plane error on crs_twice's true post-cut states 1.5 mm
    against 9.9 mm regressed in metres: docs/policies.md).

    Attributes:
        noise: half-width of the uniform point noise on training samples.
        val_fraction: share of demonstrations held out (split by demonstration with the loop's seed; the
            best epoch is kept).
        start_step: the policy's step counter when it starts at the predicted pose (stored in ``reset.json``).
        points: points of the dough and of the goal fed to the regressor (each).
        draws: at inference, average the offset over this many point subsamples (stored in ``reset.json``).
        target: ``tool`` (regress the tool ``x``) or ``skill`` (the skill's ``reset_target`` of it, e.g.
            the cut's plane and phase; docs/policies.md, "The cut's reset pose and the grid cell").
        decoded_goals: probability that a goal piece of a training sample is replaced by its VAE
            reconstruction (``encoder_weights``; empty: the shipped VAE), as at execution.
        decoded_noise: std of Gaussian noise on the shape code of those reconstructions (4 per piece).
        piece_share: every goal point also carries its piece's share of the goal's points (an input).
        x_share: regress the first value as the share of the dough's points below it, as its difference from
            the goal's leftmost piece's share (``ResetConfig.x_share`` and ``share_prior``: the plane's prior).
        encoder_weights: the VAE directory for ``decoded_goals`` (empty: the shipped VAE).
    """

    noise: float = 0.002
    val_fraction: float = 0.1
    start_step: int = 0
    points: int = 1000
    draws: int = 1
    target: str = "skill"
    decoded_goals: float = 0.5
    decoded_noise: float = 0.5
    piece_share: bool = True
    x_share: bool = True
    encoder_weights: str = ""

    def __post_init__(self) -> None:
        from pasta.config.validate import check_ranges
        from pasta.train.vae import MAX_POINTS

        if self.target not in ("tool", "skill"):
            raise ConfigError(f"target must be tool or skill, got {self.target!r}")
        check_ranges(self, {"noise": (0.0, None), "val_fraction": (0.0, 1.0, "[)"), "start_step": (0, None),
                            "points": (1, MAX_POINTS), "draws": (1, 10_000), "decoded_goals": (0.0, 1.0),
                            "decoded_noise": (0.0, None)})


#: the trainer's held-out figures, beside ``reset.*`` (the pipeline's done file of a ``reset`` unit)
METRICS = "reset_metrics.json"


def reset_configs(overrides: Mapping[str, Any] | None = None, *, command: str = "pasta train reset") -> tuple[LoopConfig, ResetTrainConfig]:
    """The loop's and the trainer's settings from ``key=value`` overrides over :data:`LOOP_DEFAULTS` (a
    typo fails with the closest valid key)."""
    from pasta.config.overrides import build_many

    loop, cfg = build_many({**LOOP_DEFAULTS, **dict(overrides or {})}, [LoopConfig, ResetTrainConfig], command=command)
    if cfg.decoded_goals > 0:
        check_encoder_weights(cfg.encoder_weights)
    return loop, cfg


def reset_command(data: str | Path, out: str | Path, skill: str,
                  overrides: dict[str, Any] | None = None) -> dict[str, Any]:
    """Train the reset-pose regressor of ``skill`` on the demonstrations in ``data`` and write it to
    ``out/reset.*`` (``out``: the policy's directory, beside its ``model.*``) with ``out/reset_metrics.json``;
    return the metrics. ``overrides``: :class:`~pasta.train.loop.LoopConfig` and :class:`ResetTrainConfig` keys."""
    from pasta.demos.data import load_demos, split_by_demo
    from pasta.plugins import get_plugins

    loop, cfg = reset_configs(overrides)
    skill_obj = get_plugins().skills.create(skill)
    with torch_threads(loop.threads):  # data preparation too, not only the loop
        demos = load_demos(data, [skill], stage="reset")
        train, val = split_by_demo(demos, val_fraction=cfg.val_fraction, seed=loop.seed)
        outputs = len(skill_obj.reset_target(0.5)) if cfg.target == "skill" else 1
        net_cfg = ResetConfig(start_step=cfg.start_step, points=cfg.points, draws=cfg.draws, target=cfg.target,
                              outputs=outputs, piece_share=cfg.piece_share, x_share=cfg.x_share,
                              share_prior=cfg.x_share)
        encoder = None
        if cfg.decoded_goals > 0:
            encoder = load_encoder(cfg.encoder_weights)
        _, metrics = train_reset(train, val, net_cfg, out=out, loop=loop, noise=cfg.noise, skill=skill_obj,
                                 encoder=encoder, decoded_goals=cfg.decoded_goals, decoded_noise=cfg.decoded_noise)
    metrics = {"module": MODULE, "skill": skill, "data": str(data), "start_step": cfg.start_step, **metrics}
    write_json(Path(out) / METRICS, metrics)
    return metrics


def train_command(data: str | Path, out: str | Path, overrides: dict[str, Any] | None = None) -> dict[str, Any]:
    """``pasta train reset data=DIR out=MODELS skill=NAME [key=value ...]`` as a function: :func:`reset_command`
    into the policy's directory ``MODELS/policy/<skill>`` (``reset.*`` beside its ``model.*``); returns the metrics."""
    from pasta.policy import POLICY_DIR

    pairs = dict(overrides or {})
    skill = pairs.pop("skill", "")
    if not skill:
        raise ConfigError("`pasta train reset` needs skill=NAME (its demonstrations in DATA/NAME)")
    return reset_command(data, Path(out) / POLICY_DIR / skill, skill, pairs)
