"""Behaviour-cloning data for one skill: demonstrations with hindsight goals.

Demonstration format (written by ``pasta demos``): ``DIR/<skill>/demo_00000.npz`` with ``dough``
``(T+1, P, 3)``, ``tool_points`` ``(T+1, Tp, 3)``, ``tool_pose`` ``(T+1, 7)``, ``action`` ``(T, A)``,
``skill`` and ``params`` (0-d strings).

A training sample is a time step ``t`` of a demo and a goal:

- with probability ``1 - hindsight_ratio`` the demo's final state ``dough[T]``; the done label is 1
  exactly at the last action, ``t = T - 1``;
- otherwise a hindsight goal: the state ``dough[t' + 1]`` reached by a later action ``t'`` drawn
  uniformly from ``[t, T - 1]``; the done label is 1 exactly when ``t = t'`` (the current action is
  the one that reaches the goal).

The released PASTA code pairs these labels with the wrong goal type (its reference §5.5); here the
label always belongs to the goal actually fed to the network. Every point gets uniform noise in
``[-noise, noise]`` (0.005) during training. All randomness comes from the generator passed in.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pasta.core.errors import InputError, MissingComponentError

__all__ = ["Batch", "DemoSet", "load_demos", "split_demos"]


@dataclass
class Batch:
    """One training batch (numpy float32): ``dough (B, P, 3)``, ``tool (B, T, 3)``, ``goal (B, G, 3)``,
    ``action (B, A)``, ``done (B,)`` in {0, 1}."""

    dough: np.ndarray
    tool: np.ndarray
    goal: np.ndarray
    action: np.ndarray
    done: np.ndarray


@dataclass
class Demo:
    dough: np.ndarray  # (T+1, P, 3)
    tool_points: np.ndarray  # (T+1, Tp, 3)
    action: np.ndarray  # (T, A)
    path: str


def demo_files(data: str | Path, skill: str) -> list[Path]:
    """The sorted demo files of ``skill`` under ``data``."""
    files = sorted(Path(data, skill).glob("demo_*.npz"))
    if not files:
        raise MissingComponentError(f"no demonstrations of '{skill}' in {Path(data, skill)}: run `pasta demos` first")
    return files


def load_demos(files: list[Path], skill: str | None = None) -> list[Demo]:
    """Read demo files (no pickle); check shapes and that each is a demo of ``skill``."""
    out = []
    for f in files:
        with np.load(f, allow_pickle=False) as z:
            dough, tool, action = (np.asarray(z[k], np.float32) for k in ("dough", "tool_points", "action"))
            name = str(z["skill"]) if "skill" in z else None
        t = action.shape[0]
        if dough.ndim != 3 or dough.shape[0] != t + 1 or tool.shape[0] != t + 1 or action.ndim != 2 or t < 1:
            raise InputError(f"{f}: expected dough (T+1, P, 3), tool_points (T+1, Tp, 3), action (T, A) with T >= 1, "
                             f"got {dough.shape}, {tool.shape}, {action.shape}")
        if skill is not None and name is not None and name != skill:
            raise InputError(f"{f} is a demo of '{name}', not '{skill}'")
        out.append(Demo(dough, tool, action, str(f)))
    dims = {d.action.shape[1] for d in out}
    if len(dims) > 1:
        raise InputError(f"demos of one skill must share one action size, got {sorted(dims)}")
    return out


def split_demos(files: list[Path], val_fraction: float, seed: int) -> tuple[list[Path], list[Path]]:
    """Split by demonstration (never inside one), seeded. At least one demo stays for training."""
    rng = np.random.default_rng(seed)
    order = rng.permutation(len(files))
    n_val = min(int(round(len(files) * val_fraction)), len(files) - 1)
    val = sorted(files[i] for i in order[:n_val])
    train = sorted(files[i] for i in order[n_val:])
    return train, val


def _subsample(cloud: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """``(n, 3)`` points of ``cloud (P, 3)`` (without replacement when ``P >= n``)."""
    return cloud[rng.choice(len(cloud), size=n, replace=len(cloud) < n)]


class DemoSet:
    """Samples behaviour-cloning batches with hindsight goals from a list of demos.

    Args:
        demos: the demonstrations (one skill).
        dough_points, tool_points, goal_points: points per source in a sample.
        hindsight_ratio: probability of a hindsight goal instead of the final state.
        noise: half-width of the uniform point noise (0 to disable, e.g. for validation).
    """

    def __init__(self, demos: list[Demo], *, dough_points: int = 512, tool_points: int = 100, goal_points: int = 512,
                 hindsight_ratio: float = 0.5, noise: float = 0.005) -> None:
        if not demos:
            raise InputError("DemoSet needs at least one demonstration")
        self.demos = demos
        self.sizes = (dough_points, tool_points, goal_points)
        self.hindsight_ratio = hindsight_ratio
        self.noise = noise
        lengths = np.array([d.action.shape[0] for d in demos])
        self.index = np.concatenate([np.stack([np.full(n, i), np.arange(n)], 1) for i, n in enumerate(lengths)])

    @property
    def action_dim(self) -> int:
        return int(self.demos[0].action.shape[1])

    def __len__(self) -> int:
        """Number of (demo, step) transitions."""
        return len(self.index)

    def sample(self, rows: np.ndarray, rng: np.random.Generator) -> Batch:
        """The batch of transitions ``rows`` (indices into ``self.index``), goals and noise drawn from ``rng``."""
        p, tp, gp = self.sizes
        out = {k: [] for k in ("dough", "tool", "goal", "action", "done")}
        for r in rows:
            di, t = self.index[r]
            demo = self.demos[di]
            last = demo.action.shape[0] - 1
            if rng.random() < self.hindsight_ratio:
                tg = int(rng.integers(t, last + 1))  # the action that reaches the goal
            else:
                tg = last
            out["dough"].append(_subsample(demo.dough[t], p, rng))
            out["tool"].append(_subsample(demo.tool_points[t], tp, rng))
            out["goal"].append(_subsample(demo.dough[tg + 1], gp, rng))
            out["action"].append(demo.action[t])
            out["done"].append(float(t == tg))
        b = {k: np.asarray(np.stack(v), np.float32) for k, v in out.items()}
        if self.noise > 0:
            for k in ("dough", "tool", "goal"):
                b[k] = b[k] + rng.uniform(-self.noise, self.noise, b[k].shape).astype(np.float32)
        return Batch(**b)


def demo_params(path: str | Path) -> dict:
    """The expert parameters stored in a demo file (``params`` JSON)."""
    with np.load(path, allow_pickle=False) as z:
        return json.loads(str(z["params"])) if "params" in z else {}
