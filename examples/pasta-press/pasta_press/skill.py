"""The press skill: the plate comes down on a piece and flattens it.

The plugin gives no scripted expert and no heuristic controller, only what trajectory optimisation needs:

- ``demo_scene``: one block of dough;
- ``demo_target``: the block flattened to a drawn fraction of its height, its footprint widened about its
  centre so that its volume is kept (what a press does to a plastic material);
- ``approach_pose``: the plate centred over the piece, just above it.

``pasta demos skill=press`` then finds the plate's moves toward each target by gradient descent through the
differentiable simulator, and the learned policy trained on them is the skill's controller.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from pasta.core import InputError, Skill, ToolPose
from pasta_press.plugin import PLATE, PLATE_HALF, SPEC, PressConfig


def flattened(piece: np.ndarray, keep: float, floor_y: float) -> np.ndarray:
    """``piece (P, 3)`` pressed to ``keep`` (0, 1] of its height above ``floor_y``, widened by ``1 / sqrt(keep)``
    in x and z about its centroid (same volume)."""
    if not 0.0 < keep <= 1.0:
        raise InputError(f"press: keep must be in (0, 1], got {keep}")
    piece = np.asarray(piece, np.float64)
    out = piece.copy()
    centre = piece[:, [0, 2]].mean(0)
    out[:, [0, 2]] = centre + (piece[:, [0, 2]] - centre) / math.sqrt(keep)
    out[:, 1] = floor_y + (piece[:, 1] - floor_y) * keep
    return out.astype(np.float32)


def floor_height(points: np.ndarray) -> float:
    """Height of the floor under ``points (P, 3)``: their lowest points rest on it."""
    return float(np.percentile(np.asarray(points, np.float64)[:, 1], 1))


class PressSkill(Skill):
    """flatten a piece with the plate (1 -> 1 entities, tool: plate)."""

    spec = SPEC
    sweep_half_width = PLATE_HALF[2]
    #: the optimiser's budget (its demonstrations, task goals and evaluation): 24 env steps at full speed reach
    #: the plate's stop from the tallest block, and on the shipped demonstrations the lowest loss came at
    #: iteration 7 to 12 of 12 (Adam from zero actions, learning rate 0.1)
    training_defaults: ClassVar[Mapping[str, Mapping[str, Any]]] = {"demos": {"trajopt_steps": 24,
                                                                              "trajopt_iterations": 12}}

    def __init__(self, config: PressConfig | None = None) -> None:
        super().__init__(config if config is not None else PressConfig())

    @property
    def max_steps(self) -> int:
        return int(self.config.max_steps)

    def demo_scene(self, rng: np.random.Generator, floor_y: float, variant: str = "default") -> list:
        """One tall block, 4.5-5.5 cm a side and 8.5-10 cm tall, in the middle of the workspace (pressed to a
        third of its height, it changes by a Chamfer distance of 6e-4 to 1.4e-3 m^2: more than the 5e-4 within
        which pasta takes a piece for its goal, so the planner sees the step)."""
        height = rng.uniform(0.085, 0.1)
        size = (rng.uniform(0.045, 0.055), height, rng.uniform(0.045, 0.055))
        return [((rng.uniform(0.45, 0.55), floor_y + height / 2, rng.uniform(0.45, 0.55)), size)]

    def demo_target(self, dough: np.ndarray, rng: np.random.Generator, variant: str = "default") -> np.ndarray:
        keep = rng.uniform(self.config.flatten_min, self.config.flatten_max)
        return flattened(dough, keep, floor_height(dough))

    def approach_pose(self, piece: np.ndarray, goal: np.ndarray | None = None, scene: np.ndarray | None = None) -> ToolPose:
        piece = np.asarray(piece, np.float64)
        top = float(np.percentile(piece[:, 1], 99))
        x, z = piece[:, [0, 2]].mean(0)
        return ToolPose((float(x), top + self.config.clearance + PLATE_HALF[1], float(z)), 0.0)

    def park_pose(self) -> ToolPose:
        return ToolPose(PLATE.park, 0.0)
