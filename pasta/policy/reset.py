"""Learned reset (start) pose of a skill's tool, as PASTA's policies output it.

:class:`ResetPoseNet` is a small PointNet over the dough and the sub-goal (each centred on the dough
centroid in ``x, z``; a fourth input channel tells the two sources apart) with mean + max pooling; it
regresses the tool's ``x`` offset from the dough centroid at the end of the expert's align phase: the
first demonstration step whose action has a vertical component (where the knife starts descending).

The learned controller then starts there (:meth:`pasta.policy.learned.LearnedPolicy.approach_pose`),
with its step counter at ``start_step`` (stored in the checkpoint, chosen on validation configs).

Checkpoint: ``DIR/reset.safetensors`` + ``DIR/reset.json`` (module ``"reset_pose"``) beside the policy's
``DIR/model.*``. Train with
``python -m pasta.policy.reset data=data/demos skill=cut out=DIR [epochs=300] [seed=0] [start_step=1] [threads=1]``
(any :class:`ResetTrainConfig` key; held-out error in ``DIR/reset_metrics.json``), or in ``pasta pipeline``
(stage ``reset``: epochs 45, start_step 0, the shipped settings).
"""

from __future__ import annotations

import json
import sys
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

__all__ = ["MODULE", "ResetConfig", "ResetPoseNet", "ResetTrainConfig", "align_offset", "load_reset", "reset_command",
           "reset_inputs", "train_reset"]

#: checkpoint module (and file) name of a reset-pose regressor
MODULE = "reset_pose"
NAME = "reset"


@dataclass
class ResetConfig:
    """Sizes of :class:`ResetPoseNet`; ``scale``: metres per unit of the regressed offset;
    ``start_step``: the policy's step counter when it starts from the predicted pose; ``draws``: at
    inference, the offset is the mean over this many seeded point subsamples (1: one, as trained)."""

    points: int = 512
    widths: list[int] = field(default_factory=lambda: [64, 128, 256])
    head: list[int] = field(default_factory=lambda: [256, 64])
    scale: float = 0.05
    start_step: int = 1
    draws: int = 1

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> ResetConfig:
        return cls(**{k: v for k, v in d.items() if k in cls.__dataclass_fields__})


def _mlp(sizes: Sequence[int], last_act: bool = True) -> nn.Sequential:
    layers: list[nn.Module] = []
    for i, (a, b) in enumerate(zip(sizes[:-1], sizes[1:])):
        layers.append(nn.Linear(a, b))
        if last_act or i < len(sizes) - 2:
            layers.append(nn.ReLU())
    return nn.Sequential(*layers)


class ResetPoseNet(nn.Module):
    """``points (B, N, 4)`` (x, y, z, source: 0 dough / 1 goal) -> offset ``(B,)`` in metres."""

    def __init__(self, cfg: ResetConfig | None = None) -> None:
        super().__init__()
        self.cfg = cfg or ResetConfig()
        self.point_mlp = _mlp([4, *self.cfg.widths])
        self.head = _mlp([4 * self.cfg.widths[-1], *self.cfg.head, 1], last_act=False)

    def forward(self, points: torch.Tensor) -> torch.Tensor:
        src = points[..., 3:4]
        h = self.point_mlp(torch.cat([points[..., :3] / 0.05, src], -1))
        pooled = []
        for w in (1.0 - src, src):  # pool each source on its own
            n = w.sum(1).clamp_min(1.0)
            pooled.append((h * w).sum(1) / n)
            pooled.append((h * w - (1.0 - w) * 1e4).amax(1))
        return self.head(torch.cat(pooled, -1)).squeeze(-1) * self.cfg.scale


def reset_inputs(dough: np.ndarray, goal: np.ndarray, n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """``(2n, 4)`` network input (``n`` points of each, centred on the dough centroid in ``x, z``) and
    the centroid ``(3,)``."""
    dough = np.asarray(dough, np.float32)
    goal = np.asarray(goal, np.float32)
    c = dough.mean(0)
    shift = np.array([c[0], 0.0, c[2]], np.float32)
    d = dough[rng.choice(len(dough), n, replace=len(dough) < n)] - shift
    g = goal[rng.choice(len(goal), n, replace=len(goal) < n)] - shift
    pts = np.concatenate([np.concatenate([d, np.zeros((n, 1), np.float32)], 1),
                          np.concatenate([g, np.ones((n, 1), np.float32)], 1)], 0)
    return pts, c


def align_offset(demo: Any) -> tuple[float, int]:
    """The demo's tool ``x`` minus the initial dough centroid ``x`` at its first step with a vertical
    action component, and that step's index."""
    vertical = np.flatnonzero(np.abs(np.asarray(demo.action)[:, 1]) > 0)
    k = int(vertical[0]) if len(vertical) else 0
    return float(demo.tool_pose[k, 0] - np.asarray(demo.dough[0])[:, 0].mean()), k


class ResetPose:
    """A loaded regressor: :meth:`offset` of the tool ``x`` from the piece centroid."""

    def __init__(self, net: ResetPoseNet, seed: int = 0) -> None:
        self.net = net.eval()
        self.seed = seed

    @property
    def start_step(self) -> int:
        return int(self.net.cfg.start_step)

    @torch.no_grad()
    def offset(self, piece: np.ndarray, goal: np.ndarray) -> float:
        """The predicted offset; the mean over ``cfg.draws`` subsamples (seeds ``seed``, ``seed + 1``, ...)."""
        draws = max(1, int(self.net.cfg.draws))
        pts = [reset_inputs(piece, goal, self.net.cfg.points, np.random.default_rng(self.seed + i))[0] for i in range(draws)]
        return float(self.net(torch.as_tensor(np.stack(pts))).mean())


def load_reset(directory: str | Path) -> ResetPose | None:
    """The regressor in ``DIR/reset.*``, or ``None`` when the directory has none."""
    from pasta.io.checkpoint import checkpoint_exists, load_checkpoint

    if not checkpoint_exists(directory, NAME):
        return None
    ckpt = load_checkpoint(directory, module=MODULE, name=NAME)
    net = ResetPoseNet(ResetConfig.from_dict(ckpt.config["network"]))
    net.load_state_dict(ckpt.tensors)
    return ResetPose(net)


def _dataset(demos: Sequence[Any]) -> list[tuple[np.ndarray, np.ndarray, float, int]]:
    out = []
    for d in demos:
        off, k = align_offset(d)
        out.append((np.asarray(d.dough[0], np.float32), np.asarray(d.after, np.float32), off, k))
    return out


def _batch(items: Sequence[tuple], n: int, rng: np.random.Generator, noise: float) -> tuple[torch.Tensor, torch.Tensor]:
    xs, ys = [], []
    for dough, goal, off, _ in items:
        pts, _ = reset_inputs(dough, goal, n, rng)
        if noise > 0:
            pts[:, :3] += rng.uniform(-noise, noise, pts[:, :3].shape).astype(np.float32)
        xs.append(pts)
        ys.append(off)
    return torch.as_tensor(np.stack(xs)), torch.as_tensor(np.array(ys, np.float32))


def train_reset(train: Sequence[Any], val: Sequence[Any], cfg: ResetConfig | None = None, *, epochs: int = 300,
                batch_size: int = 32, lr: float = 1e-3, noise: float = 0.002, seed: int = 0,
                log: bool = False) -> tuple[ResetPoseNet, dict[str, Any]]:
    """Fit the regressor on ``train`` demos (their align offsets), keep the epoch with the lowest mean
    absolute error on ``val`` (``train`` itself when empty); returns the net and its metrics."""
    cfg = cfg or ResetConfig()
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    tr, va = _dataset(train), _dataset(val or train)
    net = ResetPoseNet(cfg)
    opt = torch.optim.Adam(net.parameters(), lr=lr)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, max(1, epochs))
    vx, vy = _batch(va, cfg.points, np.random.default_rng(seed + 1), 0.0)
    best, best_state, best_epoch = float("inf"), None, -1
    for epoch in range(epochs):
        net.train()
        order = rng.permutation(len(tr))
        for i in range(0, len(order), batch_size):
            x, y = _batch([tr[j] for j in order[i:i + batch_size]], cfg.points, rng, noise)
            loss = nn.functional.smooth_l1_loss(net(x) / cfg.scale, y / cfg.scale, beta=0.05)
            opt.zero_grad()
            loss.backward()
            opt.step()
        sched.step()
        net.eval()
        with torch.no_grad():
            mae = float((net(vx) - vy).abs().mean())
        if mae < best:
            best, best_epoch = mae, epoch
            best_state = {k: v.detach().clone() for k, v in net.state_dict().items()}
        if log and (epoch % 20 == 0 or epoch == epochs - 1):
            print(f"epoch {epoch} loss {loss.item():.4f} val MAE {mae * 1000:.2f} mm (best {best * 1000:.2f})",
                  file=sys.stderr, flush=True)
    net.load_state_dict(best_state)
    net.eval()
    with torch.no_grad():
        err = (net(vx) - vy).abs().numpy()
    metrics = {"train_demos": len(tr), "heldout_demos": len(va), "best_epoch": best_epoch,
               "heldout_mae_m": float(err.mean()), "heldout_median_ae_m": float(np.median(err)),
               "heldout_max_ae_m": float(err.max()), "target_std_m": float(np.std([t[2] for t in va])),
               "demo_align_steps_median": float(np.median([t[3] for t in tr]))}
    return net, metrics


@dataclass
class ResetTrainConfig:
    """Settings of :func:`reset_command` (``python -m pasta.policy.reset`` and the pipeline's ``reset`` stage).

    Attributes:
        epochs: passes over the training demonstrations (the shipped regressor: 45).
        batch_size, lr, noise: optimiser batch, Adam learning rate (cosine-annealed), point noise half-width.
        seed: seed of the split, the initialisation and the batches.
        val_fraction: share of demonstrations held out (split by demonstration; the best epoch is kept).
        start_step: the policy's step counter when it starts at the predicted pose (stored in ``reset.json``).
        points: points of the dough and of the goal fed to the regressor (each).
        draws: at inference, average the offset over this many point subsamples (stored in ``reset.json``).
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
    threads: int = 1
    progress: bool = True


def reset_command(data: str | Path, out: str | Path, skill: str,
                  overrides: dict[str, Any] | None = None) -> dict[str, Any]:
    """Train the reset-pose regressor of ``skill`` on the demonstrations in ``data`` and write it to
    ``out/reset.*`` (beside the policy's ``model.*``) with ``out/reset_metrics.json``; return the metrics.
    ``overrides``: :class:`ResetTrainConfig` keys (a typo fails with the closest valid key)."""
    from pasta.config.overrides import build
    from pasta.io.checkpoint import save_checkpoint
    from pasta.train.data import load_demos, split_by_demo

    from pasta.train.loop import torch_threads

    cfg = build(ResetTrainConfig, dict(overrides or {}), command="python -m pasta.policy.reset")
    demos = load_demos(data, [skill])
    train, val = split_by_demo(demos, val_fraction=cfg.val_fraction, seed=cfg.seed)
    net_cfg = ResetConfig(start_step=cfg.start_step, points=cfg.points, draws=cfg.draws)
    with torch_threads(cfg.threads):
        net, metrics = train_reset(train, val, net_cfg, epochs=cfg.epochs, batch_size=cfg.batch_size, lr=cfg.lr,
                                   noise=cfg.noise, seed=cfg.seed, log=cfg.progress)
    out = Path(out)
    save_checkpoint(out, module=MODULE, name=NAME, tensors=net.state_dict(),
                    config={"skill": skill, "network": asdict(net_cfg)}, state=metrics)
    metrics = {"module": MODULE, "skill": skill, "data": str(data), "start_step": cfg.start_step, **metrics}
    (out / "reset_metrics.json").write_text(json.dumps(metrics, indent=2) + "\n")
    return metrics


def main(argv: Sequence[str] | None = None) -> int:
    args = dict(a.split("=", 1) for a in (sys.argv[1:] if argv is None else argv))
    data, skill = args.pop("data", "data/demos"), args.pop("skill", "")
    if not skill:
        raise SystemExit("python -m pasta.policy.reset: give skill=NAME (its demonstrations in DATA/NAME)")
    out = args.pop("out")
    metrics = reset_command(data, out, skill, args)
    print(json.dumps(metrics, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
