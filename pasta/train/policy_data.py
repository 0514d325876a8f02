"""Behaviour-cloning data for one skill: demonstrations with hindsight goals.

Demonstrations are read with the shared reader :mod:`pasta.demos.data` (``DIR/<skill>/demo_00000.npz``
with ``dough (T+1, P, 3)``, ``tool_points (T+1, Tp, 3)``, ``action (T, A)``, ...).

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

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from pasta.core.errors import InputError
from pasta.demos.data import Demo
from pasta.train.decoded import DecodedPieces, goal_draw

__all__ = ["Batch", "DemoSet"]


@dataclass
class Batch:
    """One training batch (numpy float32): ``dough (B, P, 3)``, ``tool (B, T, 3)``, ``goal (B, G, 3)``,
    ``action (B, A)``, ``done (B,)`` in {0, 1}, ``step (B,)`` the step index ``t`` of each sample within its
    demonstration (actions taken before it), ``pose (B, 7)`` the tool pose at that step, ``prev_action (B, A)``
    the action before it (zeros at ``t = 0``)."""

    dough: np.ndarray
    tool: np.ndarray
    goal: np.ndarray
    action: np.ndarray
    done: np.ndarray
    step: np.ndarray | None = None
    pose: np.ndarray | None = None
    prev_action: np.ndarray | None = None


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
        decoded: per demonstration, the pieces of its final state with their VAE reconstructions
            (:func:`pasta.train.decoded.decoded_pieces`); a final-state goal (not a hindsight one) has each
            piece replaced by a reconstruction with probability ``p_decoded``, moved by up to
            ``decoded_shift`` per axis (:func:`pasta.train.decoded.goal_draw`): the sub-goals a plan hands
            the policy at execution.
    """

    def __init__(self, demos: Sequence[Demo], *, dough_points: int = 512, tool_points: int = 100, goal_points: int = 512,
                 hindsight_ratio: float = 0.5, noise: float = 0.005, decoded: Sequence[DecodedPieces] | None = None,
                 p_decoded: float = 0.0, decoded_shift: float = 0.0) -> None:
        if not demos:
            raise InputError("DemoSet needs at least one demonstration")
        dims = {d.action.shape[1] for d in demos}
        if len(dims) > 1:
            raise InputError(f"demonstrations of one skill must share one action size, got {sorted(dims)}")
        if any(d.action.shape[0] < 1 or d.dough.shape[0] != d.action.shape[0] + 1 for d in demos):
            raise InputError("every demonstration needs T >= 1 actions and T + 1 dough clouds")
        self.demos = list(demos)
        self.sizes = (dough_points, tool_points, goal_points)
        self.hindsight_ratio = hindsight_ratio
        self.noise = noise
        if decoded is not None and len(decoded) != len(self.demos):
            raise InputError(f"decoded goals for {len(decoded)} demonstrations, but there are {len(self.demos)}")
        self.decoded, self.p_decoded, self.decoded_shift = decoded, p_decoded, decoded_shift
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
        out: dict[str, list[Any]] = {k: [] for k in ("dough", "tool", "goal", "action", "done", "step", "pose",
                                                     "prev_action")}
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
            goal = demo.dough[tg + 1]
            if self.decoded is not None and tg == last:
                goal = goal_draw(goal, self.decoded[di], self.p_decoded, rng, self.decoded_shift)
            out["goal"].append(_subsample(goal, gp, rng))
            out["action"].append(demo.action[t])
            out["done"].append(float(t == tg))
            out["step"].append(float(t))
            out["pose"].append(demo.tool_pose[t])
            out["prev_action"].append(demo.action[t - 1] if t > 0 else np.zeros_like(demo.action[t]))
        b = {k: np.asarray(np.stack(v), np.float32) for k, v in out.items()}
        if self.noise > 0:
            for k in ("dough", "tool", "goal"):
                b[k] = b[k] + rng.uniform(-self.noise, self.noise, b[k].shape).astype(np.float32)
        return Batch(**b)

