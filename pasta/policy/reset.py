"""Learned reset (start) pose of a skill's tool, as PASTA's policies output it.

:class:`ResetPoseNet` is a small PointNet over the dough and the sub-goal (each centred on the dough
centroid in ``x, z``; a fourth input channel tells the two sources apart) with mean + max pooling; it
regresses the tool's ``x`` offset from the dough centroid at the end of the expert's align phase: the
first demonstration step whose action has a vertical component (where the knife starts descending).
With ``target="skill"`` it regresses the skill's :meth:`~pasta.core.skill.Skill.reset_target` of that
``x`` instead (the cut: the plane where the dough parts and the knife's phase in its grid cell), and the
skill turns the prediction back into a tool ``x`` (:meth:`~pasta.core.skill.Skill.reset_tool_x`).

The learned controller then starts there (:meth:`pasta.policy.learned.LearnedPolicy.approach_pose`),
with its step counter at ``start_step`` (stored in the checkpoint, chosen on validation configs).

Checkpoint: ``DIR/reset.safetensors`` + ``DIR/reset.json`` (module ``"reset_pose"``) beside the policy's
``DIR/model.*``; the trainer is :mod:`pasta.train.reset`. This module is the runtime half: the network,
its inputs and the loaded regressor.
"""

from __future__ import annotations

import itertools
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch
from torch import nn

from pasta.core.decompose import decompose_labels

__all__ = ["MODULE", "NAME", "ResetConfig", "ResetPose", "ResetPoseNet", "left_piece_share", "load_reset", "piece_shares",
           "reset_inputs", "x_at_share"]

#: units of a regressed share (``x_share``): shares spread about 4x as wide as offsets in 5 cm units, so the
#: loss weighs both outputs of the cut's (share, phase) as it did (plane, phase)
SHARE_SCALE = 0.2
#: config keys added after checkpoints were written without them, with the value that reads those checkpoints
#: as they were trained
ADDED_KEYS = {"share_prior": False}
#: checkpoint module (and file) name of a reset-pose regressor
MODULE = "reset_pose"
NAME = "reset"


@dataclass
class ResetConfig:
    """Sizes of :class:`ResetPoseNet`; ``scale``: metres per unit of the regressed offset;
    ``start_step``: the policy's step counter when it starts from the predicted pose; ``draws``: at
    inference, the offset is the mean over this many seeded point subsamples (1: one, as trained);
    ``target``: what the offset is of, ``"tool"`` (the tool ``x``) or
    ``"skill"`` (the skill's ``reset_target`` of it, turned back by ``reset_tool_x``); ``outputs``: how
    many values the network regresses (``R``: the first an ``x`` offset in metres, the others unitless;
    ``len(skill.reset_target(x))`` for ``"skill"``); ``piece_share``: every goal point also carries its
    piece's share of the goal's points (DBSCAN pieces; the executor's goal masses make those exact);
    ``x_share``: the first value is not an ``x`` offset in metres but the share of the piece's points whose
    ``x`` lies below it (0-1), read back as that quantile of the observed piece's ``x``: a mass fraction carries
    over to pieces and cuts longer than the demonstrations' (the cut's plane from the goal pieces' point
    shares; docs/policies.md, "crs_twice with learned policies: the fix"); ``share_prior`` (with ``x_share``):
    the network regresses that share's difference from the goal's leftmost piece's share of the goal's points
    (:func:`left_piece_share`), so a piece unlike the demonstrations' (two pieces pressed together, a crease)
    does not move the plane the goal's masses fix (docs/policies.md, "The plane's prior")."""

    points: int = 512
    widths: list[int] = field(default_factory=lambda: [64, 128, 256])
    head: list[int] = field(default_factory=lambda: [256, 64])
    scale: float = 0.05
    start_step: int = 1
    draws: int = 1
    target: str = "tool"
    outputs: int = 1
    piece_share: bool = False
    x_share: bool = False
    share_prior: bool = False

    def __post_init__(self) -> None:
        if self.share_prior and not self.x_share:
            from pasta.core.errors import ConfigError

            raise ConfigError("reset pose network: share_prior needs x_share (the prior is a share of the goal's points)")

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> ResetConfig:
        """The config a checkpoint wrote (``asdict``); every key must be there (no defaults for missing ones),
        except the :data:`ADDED_KEYS` an older checkpoint lacks.

        Raises:
            ConfigError: a key is missing or unknown."""
        from pasta.policy.network import _check_keys

        d = {**ADDED_KEYS, **d}
        _check_keys("reset pose network", d, cls.__dataclass_fields__)
        return cls(**d)


def x_at_share(cloud: np.ndarray, share: float) -> float:
    """The ``x`` below which ``share`` (clipped to 0-1) of ``cloud (P, 3)``'s points lie (an ``x_share`` output)."""
    return float(np.quantile(np.asarray(cloud, np.float64)[:, 0], np.clip(share, 0.0, 1.0)))


def _mlp(sizes: Sequence[int], last_act: bool = True) -> nn.Sequential:
    layers: list[nn.Module] = []
    for i, (a, b) in enumerate(itertools.pairwise(sizes)):
        layers.append(nn.Linear(a, b))
        if last_act or i < len(sizes) - 2:
            layers.append(nn.ReLU())
    return nn.Sequential(*layers)


class ResetPoseNet(nn.Module):
    """``points (B, N, 4 or 5)`` (x, y, z, source: 0 dough / 1 goal[, piece share]) -> ``(B, R)``: the offset in metres, then
    ``R - 1`` unitless values (``R = cfg.outputs``)."""

    units: torch.Tensor  # a buffer (register_buffer)

    def __init__(self, cfg: ResetConfig | None = None) -> None:
        super().__init__()
        self.cfg = cfg or ResetConfig()
        self.point_mlp = _mlp([4 + int(self.cfg.piece_share), *self.cfg.widths])
        self.head = _mlp([4 * self.cfg.widths[-1], *self.cfg.head, self.cfg.outputs], last_act=False)
        units = torch.ones(self.cfg.outputs)
        units[0] = SHARE_SCALE if self.cfg.x_share else self.cfg.scale
        self.register_buffer("units", units, persistent=False)

    def forward(self, points: torch.Tensor) -> torch.Tensor:
        src = points[..., 3:4]
        h = self.point_mlp(torch.cat([points[..., :3] / 0.05, points[..., 3:]], -1))
        pooled = []
        for w in (1.0 - src, src):  # pool each source on its own
            n = w.sum(1).clamp_min(1.0)
            pooled.append((h * w).sum(1) / n)
            pooled.append((h * w - (1.0 - w) * 1e4).amax(1))
        return self.head(torch.cat(pooled, -1)) * self.units


def piece_shares(goal: np.ndarray, labels: np.ndarray | None = None) -> np.ndarray:
    """``(G,)``: for every point of ``goal (G, 3)`` its piece's share of the goal's points (``labels``, default
    :func:`pasta.core.decompose.decompose_labels`: DBSCAN pieces, ordered by centroid ``x``). Point counts are masses for an observed cloud, and the executor's goal masses make
    them so for a plan's sub-goals."""
    labels = decompose_labels(goal) if labels is None else labels
    return (np.bincount(labels)[labels] / len(goal)).astype(np.float32)


def left_piece_share(goal: np.ndarray, labels: np.ndarray | None = None) -> float:
    """The goal's leftmost piece's share of its points (``labels``, default :func:`~pasta.core.decompose.decompose_labels`, number the
    pieces by centroid ``x``): for a cut whose plane is ``x = const``, the share of the piece's points that
    must lie left of the plane, as dough keeps its mass. 0.5 when the goal shows one piece (it says nothing
    of the split)."""
    labels = decompose_labels(goal) if labels is None else np.asarray(labels)
    if len(labels) == 0 or labels.max() < 1:
        return 0.5
    return float(np.mean(labels == 0))


def reset_inputs(dough: np.ndarray, goal: np.ndarray, n: int, rng: np.random.Generator,
                 piece_share: bool = False, labels: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(2n, 4)`` network input (``n`` points of each, centred on the dough centroid in ``x, z``, and a
    source channel), ``(2n, 5)`` with ``piece_share`` (the goal points' :func:`piece_shares` by ``labels``,
    default :func:`~pasta.core.decompose.decompose_labels`; 0 for the dough), and the centroid ``(3,)``."""
    dough = np.asarray(dough, np.float32)
    goal = np.asarray(goal, np.float32)
    c = dough.mean(0)
    shift = np.array([c[0], 0.0, c[2]], np.float32)
    d = dough[rng.choice(len(dough), n, replace=len(dough) < n)] - shift
    gi = rng.choice(len(goal), n, replace=len(goal) < n)
    g = goal[gi] - shift
    cols_d, cols_g = [np.zeros((n, 1), np.float32)], [np.ones((n, 1), np.float32)]
    if piece_share:
        cols_d.append(np.zeros((n, 1), np.float32))
        cols_g.append(piece_shares(goal, labels)[gi, None])
    pts = np.concatenate([np.concatenate([d, *cols_d], 1), np.concatenate([g, *cols_g], 1)], 0)
    return pts, c


class ResetPose:
    """A loaded regressor: :meth:`offset` of the tool ``x`` from the piece centroid."""

    def __init__(self, net: ResetPoseNet, seed: int = 0) -> None:
        self.net = net.eval()
        self.seed = seed

    @property
    def start_step(self) -> int:
        return int(self.net.cfg.start_step)

    @property
    def target(self) -> str:
        return str(self.net.cfg.target)

    @property
    def x_share(self) -> bool:
        """Whether the first regressed value is a share of the piece's points (:class:`ResetConfig`)."""
        net = getattr(self, "net", None)
        return bool(net is not None and net.cfg.x_share)

    def tool_x(self, skill: Any, piece: np.ndarray, goal: np.ndarray) -> float:
        """The tool's start ``x`` for ``piece (P, 3)`` and ``goal (G, 3)``: the piece centroid ``x`` plus
        the predicted offset, through ``skill.reset_tool_x`` when the regressor learned the skill's target."""
        y = self.predict(piece, goal)
        y[0] = x_at_share(piece, y[0]) if self.x_share else y[0] + float(np.asarray(piece, np.float64)[:, 0].mean())
        return float(skill.reset_tool_x(tuple(float(v) for v in y))) if self.target == "skill" else float(y[0])

    @torch.no_grad()
    def predict(self, piece: np.ndarray, goal: np.ndarray) -> np.ndarray:
        """The regressed values ``(R,)`` (the first an offset from the piece centroid ``x``, or a share; with
        ``share_prior`` the goal's :func:`left_piece_share` added back); the mean over ``cfg.draws``
        subsamples (seeds ``seed``, ``seed + 1``, ...)."""
        draws = max(1, int(self.net.cfg.draws))
        cfg = self.net.cfg
        labels = decompose_labels(goal) if cfg.piece_share or cfg.share_prior else None
        pts = [reset_inputs(piece, goal, cfg.points, np.random.default_rng(self.seed + i), cfg.piece_share, labels)[0]
               for i in range(draws)]
        y = self.net(torch.as_tensor(np.stack(pts))).mean(0).numpy().astype(np.float64)
        if cfg.share_prior:
            y[0] += left_piece_share(goal, labels)
        return y

    def offset(self, piece: np.ndarray, goal: np.ndarray) -> float:
        """The predicted offset ``x`` (metres) from the piece centroid (:meth:`predict`'s first value, turned
        into metres on ``piece`` for an ``x_share`` regressor)."""
        y = float(self.predict(piece, goal)[0])
        return x_at_share(piece, y) - float(np.asarray(piece, np.float64)[:, 0].mean()) if self.x_share else y


def load_reset(directory: str | os.PathLike) -> ResetPose | None:
    """The regressor in ``DIR/reset.*``, or ``None`` when the directory has none."""
    from pasta.io.checkpoint import checkpoint_exists, load_checkpoint

    if not checkpoint_exists(directory, NAME):
        return None
    ckpt = load_checkpoint(directory, module=MODULE, name=NAME,
                           hint="train one with `pasta train reset data=DIR out=MODELS skill=NAME`")
    net = ResetPoseNet(ResetConfig.from_dict(ckpt.config["network"]))
    net.load_state_dict(ckpt.tensors)
    return ResetPose(net)
