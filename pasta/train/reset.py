"""Training of a skill's learned reset (start) pose (:mod:`pasta.policy.reset` holds the network and its loading).

The regressor learns, per demonstration, the tool's ``x`` offset from the initial dough centroid at the end
of the expert's align phase (:func:`align_offset`: the first step with a vertical action), or with
``target="skill"`` the skill's :meth:`~pasta.core.skill.Skill.reset_target` of that ``x``.

Checkpoint: ``DIR/reset.safetensors`` + ``DIR/reset.json`` beside the policy's ``DIR/model.*``, with the
held-out errors in ``DIR/reset_metrics.json`` (:func:`reset_command`, what the pipeline's ``reset`` stage runs).
"""

from __future__ import annotations

import json
import sys
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from pasta.core.errors import ConfigError
from pasta.policy.reset import MODULE, NAME, ResetConfig, ResetPoseNet, reset_inputs, x_at_share

__all__ = ["ResetTrainConfig", "align_offset", "decoded_pieces", "reset_command", "share_below", "train_reset"]


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


def decoded_pieces(goal: np.ndarray, encoder: Any, *, noise: float = 0.0, draws: int = 1,
                   rng: np.random.Generator | None = None) -> list[tuple[np.ndarray, np.ndarray]]:
    """The pieces of ``goal (G, 3)`` (DBSCAN, :func:`pasta.core.decompose.decompose_labels`), each with
    ``draws`` reconstructions by ``encoder`` ``(draws, n, 3)`` (encoded, Gaussian ``noise`` on the shape
    code ``z``, decoded to the piece's own point count ``n``): the kind of piece a plan's decoded sub-goal
    hands a policy at execution, where the planner chose the shape code. ``encoder``: a
    :class:`pasta.core.Encoder` (:meth:`~pasta.core.Encoder.decode_clouds`)."""
    from pasta.core.decompose import decompose_labels

    rng = rng or np.random.default_rng(0)
    labels = decompose_labels(goal)
    pieces = [np.asarray(goal[labels == k], np.float32) for k in range(int(labels.max()) + 1)]
    z_dim = int(getattr(encoder, "z_dim", 0))
    out = []
    for piece in pieces:
        with torch.no_grad():
            u = torch.as_tensor(encoder.encode(piece[None])).repeat(max(1, draws), 1)
        if noise > 0 and z_dim:
            u[:, :z_dim] += noise * torch.as_tensor(rng.standard_normal((len(u), z_dim)), dtype=u.dtype)
        out.append((piece, np.stack(encoder.decode_clouds(u, len(piece)))))
    return out


def _goal_draw(goal: np.ndarray, pieces: Sequence[tuple[np.ndarray, np.ndarray]] | None, p: float,
               rng: np.random.Generator) -> np.ndarray:
    """``goal`` with each of its ``pieces`` replaced by one of its reconstructions with probability ``p``."""
    if not pieces or p <= 0:
        return goal
    return np.concatenate([recs[rng.integers(len(recs))] if rng.random() < p else exact for exact, recs in pieces])


def _batch(items: Sequence[tuple], n: int, rng: np.random.Generator, noise: float,
           decoded: Sequence[Any] | None = None, p_decoded: float = 0.0,
           piece_share: bool = False) -> tuple[torch.Tensor, torch.Tensor]:
    xs, ys = [], []
    for i, (dough, goal, off, _) in enumerate(items):
        if decoded is not None:
            goal = _goal_draw(goal, decoded[i], p_decoded, rng)
        pts, _ = reset_inputs(dough, goal, n, rng, piece_share)
        if noise > 0:
            pts[:, :3] += rng.uniform(-noise, noise, pts[:, :3].shape).astype(np.float32)
        xs.append(pts)
        ys.append(off)
    return torch.as_tensor(np.stack(xs)), torch.as_tensor(np.stack(ys).astype(np.float32))


def train_reset(train: Sequence[Any], val: Sequence[Any], cfg: ResetConfig | None = None, *, epochs: int = 300,
                batch_size: int = 32, lr: float = 1e-3, noise: float = 0.002, seed: int = 0,
                log: bool = False, skill: Any = None, encoder: Any = None,
                decoded_goals: float = 0.0, decoded_noise: float = 0.0) -> tuple[ResetPoseNet, dict[str, Any]]:
    """Fit the regressor on ``train`` demos (their align offsets, or with ``cfg.target == "skill"`` the
    offsets of ``skill.reset_target``), keep the epoch with the lowest mean absolute error on ``val``
    (``train`` itself when empty); returns the net and its metrics (held-out errors in the regressed
    target and, for ``"skill"``, of the tool ``x`` the skill places from it). ``decoded_goals``: the
    probability that a training sample's goal piece is replaced by its ``encoder`` reconstruction
    (:func:`decoded_pieces`), as a plan's decoded sub-goals are at execution. Held-out errors are on the
    demonstrations' own goals."""
    cfg = cfg or ResetConfig()
    if cfg.target not in ("tool", "skill"):
        raise ValueError(f"reset target must be 'tool' or 'skill', got {cfg.target!r}")
    if cfg.target == "skill" and skill is None:
        raise ValueError("reset target 'skill' needs the skill (its reset_target)")
    own = skill if cfg.target == "skill" else None
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    tr, va = _dataset(train, own, cfg.x_share), _dataset(val or train, own, cfg.x_share)
    va_m = _dataset(val or train, own) if cfg.x_share else va  # held-out targets in metres, for the figures
    if len(tr[0][2]) != cfg.outputs:
        raise ValueError(f"the regressor has {cfg.outputs} outputs but the targets have {len(tr[0][2])} values")
    if decoded_goals > 0 and encoder is None:
        raise ValueError("decoded_goals needs the encoder that decodes the goal pieces")
    decoded = ([decoded_pieces(t[1], encoder, noise=decoded_noise, draws=4 if decoded_noise > 0 else 1, rng=rng)
                for t in tr] if decoded_goals > 0 else None)
    net = ResetPoseNet(cfg)
    opt = torch.optim.Adam(net.parameters(), lr=lr)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, max(1, epochs))
    vx, vy = _batch(va, cfg.points, np.random.default_rng(seed + 1), 0.0, piece_share=cfg.piece_share)
    best, best_state, best_epoch = float("inf"), None, -1
    for epoch in range(epochs):
        net.train()
        order = rng.permutation(len(tr))
        for i in range(0, len(order), batch_size):
            idx = order[i:i + batch_size]
            x, y = _batch([tr[j] for j in idx], cfg.points, rng, noise,
                          None if decoded is None else [decoded[j] for j in idx], decoded_goals, cfg.piece_share)
            loss = nn.functional.smooth_l1_loss(net(x) / net.units, y / net.units, beta=0.05)
            opt.zero_grad()
            loss.backward()
            opt.step()
        sched.step()
        net.eval()
        with torch.no_grad():
            mae = float((net(vx) - vy)[:, 0].abs().mean())
        if mae < best:
            best, best_epoch = mae, epoch
            best_state = {k: v.detach().clone() for k, v in net.state_dict().items()}
        if log and (epoch % 20 == 0 or epoch == epochs - 1):
            unit = "share x 1000" if cfg.x_share else "mm"
            print(f"epoch {epoch} loss {loss.item():.4f} val MAE {mae * 1000:.2f} {unit} (best {best * 1000:.2f})",
                  file=sys.stderr, flush=True)
    net.load_state_dict(best_state)
    net.eval()
    with torch.no_grad():
        pred = net(vx).numpy().astype(np.float64)
    if cfg.x_share:  # shares -> offsets in metres on each held-out dough
        for i, (dough, _, _, _) in enumerate(va):
            pred[i, 0] = x_at_share(dough, pred[i, 0]) - float(np.asarray(dough, np.float64)[:, 0].mean())
        vy = torch.as_tensor(np.stack([t[2] for t in va_m]).astype(np.float32))
    errs = np.abs(pred - vy.numpy())
    err = errs[:, 0]
    metrics = {"target": cfg.target, "train_demos": len(tr), "heldout_demos": len(va), "best_epoch": best_epoch,
               "heldout_mae_m": float(err.mean()), "heldout_median_ae_m": float(np.median(err)),
               "heldout_max_ae_m": float(err.max()), "target_std_m": float(np.std([t[2][0] for t in va_m])),
               "demo_align_steps_median": float(np.median([t[3] for t in tr]))}
    if cfg.outputs > 1:  # the unitless values (the cut: the knife's phase in its cell)
        metrics["heldout_mae_other"] = [float(v) for v in errs[:, 1:].mean(0)]
    if own is not None:  # what the tool does with it: the skill's tool x against the demos' own
        tool_err = []
        for (dough, _, _, _), d, p in zip(va, val or train, pred):
            c = float(np.asarray(dough, np.float64)[:, 0].mean())
            tool_err.append(abs(own.reset_tool_x((c + float(p[0]), *(float(v) for v in p[1:]))) - (c + align_offset(d)[0])))
        metrics.update(heldout_tool_mae_m=float(np.mean(tool_err)), heldout_tool_median_ae_m=float(np.median(tool_err)))
    return net, metrics


@dataclass
class ResetTrainConfig:
    """Settings of :func:`reset_command` (``python -m pasta.train.reset`` and the pipeline's ``reset`` stage).

    Attributes:
        epochs: passes over the training demonstrations (the shipped regressor: 45).
        batch_size, lr, noise: optimiser batch, Adam learning rate (cosine-annealed), point noise half-width.
        seed: seed of the split, the initialisation and the batches.
        val_fraction: share of demonstrations held out (split by demonstration; the best epoch is kept).
        start_step: the policy's step counter when it starts at the predicted pose (stored in ``reset.json``).
        points: points of the dough and of the goal fed to the regressor (each).
        draws: at inference, average the offset over this many point subsamples (stored in ``reset.json``).
        target: ``tool`` (regress the tool ``x``) or ``skill`` (the skill's ``reset_target`` of it, e.g.
            the cut's plane and phase; docs/policies.md, "The cut's reset pose and the grid cell").
        decoded_goals: probability that a goal piece of a training sample is replaced by its VAE
            reconstruction (``encoder_weights``; empty: the shipped VAE), as at execution.
        decoded_noise: std of Gaussian noise on the shape code of those reconstructions (4 per piece).
        piece_share: every goal point also carries its piece's share of the goal's points (an input).
        x_share: regress the first value as the share of the dough's points below it (:class:`ResetConfig`).
        threads: torch CPU threads (0: leave as is).
        progress: print the held-out error every 20 epochs (stderr).
    """

    epochs: int = 300
    batch_size: int = 32
    lr: float = 1e-3
    noise: float = 0.002
    seed: int = 0
    val_fraction: float = 0.1
    start_step: int = 1
    points: int = 512
    draws: int = 1
    target: str = "tool"
    decoded_goals: float = 0.0
    decoded_noise: float = 0.0
    piece_share: bool = False
    x_share: bool = False
    encoder_weights: str = ""
    threads: int = 1
    progress: bool = True


def reset_command(data: str | Path, out: str | Path, skill: str,
                  overrides: dict[str, Any] | None = None) -> dict[str, Any]:
    """Train the reset-pose regressor of ``skill`` on the demonstrations in ``data`` and write it to
    ``out/reset.*`` (beside the policy's ``model.*``) with ``out/reset_metrics.json``; return the metrics.
    ``overrides``: :class:`ResetTrainConfig` keys (a typo fails with the closest valid key)."""
    from pasta.config.overrides import build
    from pasta.io.checkpoint import save_checkpoint
    from pasta.plugins import get_plugins
    from pasta.demos.data import load_demos, split_by_demo

    from pasta.train.loop import torch_threads

    cfg = build(ResetTrainConfig, dict(overrides or {}), command="python -m pasta.train.reset")
    if cfg.target not in ("tool", "skill"):
        raise ConfigError(f"python -m pasta.train.reset: target must be tool or skill, got {cfg.target!r}")
    skill_obj = get_plugins().skills.create(skill)
    demos = load_demos(data, [skill], stage="reset")
    train, val = split_by_demo(demos, val_fraction=cfg.val_fraction, seed=cfg.seed)
    outputs = len(skill_obj.reset_target(0.5)) if cfg.target == "skill" else 1
    net_cfg = ResetConfig(start_step=cfg.start_step, points=cfg.points, draws=cfg.draws, target=cfg.target, outputs=outputs,
                          piece_share=cfg.piece_share, x_share=cfg.x_share)
    with torch_threads(cfg.threads):
        encoder = None
        if cfg.decoded_goals > 0:
            from pasta.nn.config import PointVAEEncoderConfig
            from pasta.nn.encoders import PointVAEEncoder

            encoder = PointVAEEncoder(PointVAEEncoderConfig(weights=cfg.encoder_weights))
        net, metrics = train_reset(train, val, net_cfg, epochs=cfg.epochs, batch_size=cfg.batch_size, lr=cfg.lr,
                                   noise=cfg.noise, seed=cfg.seed, log=cfg.progress, skill=skill_obj, encoder=encoder,
                                   decoded_goals=cfg.decoded_goals, decoded_noise=cfg.decoded_noise)
    out = Path(out)
    save_checkpoint(out, module=MODULE, name=NAME, tensors=net.state_dict(),
                    config={"skill": skill, "network": asdict(net_cfg)}, state=metrics)
    metrics = {"module": MODULE, "skill": skill, "data": str(data), "start_step": cfg.start_step, **metrics}
    (out / "reset_metrics.json").write_text(json.dumps(metrics, indent=2) + "\n")
    return metrics


def main(argv: Sequence[str] | None = None) -> int:
    from pasta.config.overrides import script_args

    args = script_args(argv, __doc__, "python -m pasta.train.reset")
    data, skill = args.pop("data", "data/demos"), args.pop("skill", "")
    if not skill:
        raise SystemExit("python -m pasta.train.reset: give skill=NAME (its demonstrations in DATA/NAME)")
    out = args.pop("out")
    metrics = reset_command(data, out, skill, args)
    print(json.dumps(metrics, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
