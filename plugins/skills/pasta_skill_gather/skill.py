"""The 'gather' skill: the gripper closes on three lumps lying in a row and presses them into one piece.

Geometry, in the horizontal (x, z) plane: the closing *axis* is the main axis of the lumps' points
together. The approach pose turns the gripper so its fingers close along the axis, centred on the lumps'
extent along it (and on their mean across it), fingers low and fully open (0.3). The motion is closing
(``open`` < 0) until the gap between the fingers' inner faces reaches the target width; the fingers
(0.14 wide) span the lumps' spread across the axis.

- expert: target gap ``width`` (parameter), drawn in [width_min, width_max];
- heuristic controller: the goal piece's extent along the axis plus ``width_offset``.

The gap is read from the observed tool points (their extent along the axis minus both fingers'
thickness), so the controllers need nothing but a :class:`pasta.core.SkillObservation`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from pasta.core import Controller, InputError, Skill, SkillObservation, ToolPose
from pasta.core.shapes import as_points
from pasta.demos.scene import lumps
from pasta_skill_gather.plugin import SPEC, GatherConfig
from pasta_skill_gather.tool import FINGER_HALF, GRIPPER, GRIPPER_PARK

OPEN = GRIPPER.channels.index("open")
ACTION_DIM = GRIPPER.action_dim
CLOSE_STEP = GRIPPER.scale("open")


def closing_axis(points: np.ndarray) -> np.ndarray:
    """Unit ``(2,)`` (x, z) main axis of ``points (P, 3)`` in the horizontal plane, pointing to +x."""
    xz = np.asarray(points, np.float64)[:, [0, 2]]
    xz = xz - xz.mean(0)
    _, vecs = np.linalg.eigh(xz.T @ xz)
    axis = vecs[:, -1]
    return axis if axis[0] >= 0 else -axis


def span_along(points: np.ndarray, axis: np.ndarray, q: float = 0.0) -> tuple[float, float]:
    """Ends of ``points (P, 3)`` along the horizontal ``axis (2,)``: the ``q`` and ``100 - q`` percentiles."""
    s = np.asarray(points, np.float64)[:, [0, 2]] @ axis
    lo, hi = np.percentile(s, [q, 100 - q])
    return float(lo), float(hi)


def finger_gap(tool_points: np.ndarray, axis: np.ndarray) -> float:
    """Current gap between the fingers' inner faces, from the observed tool points ``(T, 3)``."""
    s = np.asarray(tool_points, np.float64)[:, [0, 2]] @ axis
    return float(s.max() - s.min() - 4 * FINGER_HALF[0])


def approach(piece: np.ndarray, cfg: GatherConfig) -> ToolPose:
    """Gripper pose for ``piece (P, 3)`` (all lumps): centred on their extent along the closing axis,
    fingers ``lift`` above their bottom. The fingers start at the gripper's full aperture (0.3, what
    every placement restores), wide enough for three lumps in a row."""
    piece = np.asarray(piece, np.float64)
    axis = closing_axis(piece)
    across = np.array([-axis[1], axis[0]])
    lo, hi = span_along(piece, axis)
    mid = axis * (lo + hi) / 2 + across * float((piece[:, [0, 2]] @ across).mean())
    floor = float(np.percentile(piece[:, 1], 1))
    yaw = math.atan2(-axis[1], axis[0])  # the tool's local +x is (cos yaw, -sin yaw) in (x, z)
    return ToolPose((float(mid[0]), floor + cfg.lift + FINGER_HALF[1], float(mid[1])), yaw)


class GatherController(Controller):
    """Close the fingers until their gap is ``width`` (expert) or the goal's extent (heuristic)."""

    def __init__(self, config: GatherConfig, width: float | None = None) -> None:
        self.cfg = config
        self.width = width
        self.axis = np.array([1.0, 0.0])
        self.target = 0.0

    def reset(self, obs: SkillObservation) -> None:
        self.axis = closing_axis(obs.piece)
        if self.width is not None:
            self.target = self.width
        else:
            if obs.goal is None or len(obs.goal) == 0:
                raise InputError("gather controller: the goal piece is empty")
            lo, hi = span_along(obs.goal, self.axis, 1.0)
            self.target = hi - lo + self.cfg.width_offset

    def act(self, obs: SkillObservation) -> tuple[np.ndarray, bool]:
        action = np.zeros(ACTION_DIM, np.float32)
        remaining = finger_gap(obs.tool_points, self.axis) - self.target
        if remaining <= self.cfg.tolerance:
            return action, True
        action[OPEN] = -min(self.cfg.speed, remaining / CLOSE_STEP)
        return action, False


class GatherSkill(Skill):
    """squeeze three dough lumps into one compact piece with the gripper (3 -> 1 entities, tool: gripper)."""

    spec = SPEC
    sweep_half_width = FINGER_HALF[2]
    #: the shipped networks' settings (docs/learning.md, "The board skills"; docs/policies.md)
    training_defaults: ClassVar[Mapping[str, Mapping[str, Any]]] = {"feasibility": {"stride": 4, "epochs": 8}}

    def __init__(self, config: GatherConfig | None = None) -> None:
        super().__init__(config if config is not None else GatherConfig())

    @property
    def max_steps(self) -> int:
        return int(self.config.max_steps)

    def approach_pose(self, piece: np.ndarray, goal: np.ndarray | None = None, scene: np.ndarray | None = None) -> ToolPose:
        """Gripper around ``piece (P, 3)`` (the three lumps), fingers closing along their main axis."""
        return approach(as_points(piece, "piece"), self.config)

    def expert_approach_pose(self, piece: np.ndarray, params: dict[str, float], scene: np.ndarray | None = None) -> ToolPose:
        return approach(as_points(piece, "piece"), self.config)

    def park_pose(self) -> ToolPose:
        return ToolPose(GRIPPER_PARK, 0.0)

    def sample_expert_params(self, piece: np.ndarray, rng: np.random.Generator) -> dict[str, float]:
        """``width`` U(width_min, width_max), at most ``max_fraction`` of the lumps' extent along the axis."""
        piece = as_points(piece, "piece")
        lo, hi = span_along(piece, closing_axis(piece))
        cfg = self.config
        return {"width": float(min(rng.uniform(cfg.width_min, cfg.width_max), cfg.max_fraction * (hi - lo)))}

    def expert(self, params: dict[str, float]) -> Controller:
        if "width" not in params:
            raise InputError(f"gather expert needs the parameter 'width'; got {sorted(params)}")
        return GatherController(self.config, float(params["width"]))

    def controller(self) -> Controller:
        return GatherController(self.config)

    def demo_scene(self, rng: np.random.Generator, floor_y: float, variant: str = "default") -> list:
        """Three lumps in a row along x (:func:`pasta.demos.scene.lumps`), right of the board (x 0.5-0.85)."""
        return lumps(rng, floor_y, (0.6, 0.75), (0.4, 0.6))
