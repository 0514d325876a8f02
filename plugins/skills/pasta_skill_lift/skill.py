"""The 'lift' skill: carry one dough piece on the spatula and set it down on a raised surface (the board).

The spatula is a flat plate (0.14 x 0.03 x 0.14, friction 50) moved by ``(dx, dy, dz)`` in ``[-1, 1]``
(0.01 per env step). The approach pose slides it under the piece: centred below the piece's centroid,
its top ``scoop_depth`` above the piece's bottom. One execution has three phases:

1. rise until the plate's top is ``clearance`` above the destination surface;
2. carry: move horizontally until the piece's centroid (tracked, not the plate's) is at the target;
3. set down: lower the plate until its top is ``sink`` below the surface; the surface (the board, a
   static tool) stops the dough while the plate passes below it (the simulator's tools do not collide).

The expert gets the target centroid ``(target_x, target_z)`` and the surface height ``surface_y``; the
heuristic controller reads them off the goal piece (its centroid and its bottom, the 1st percentile of
y: the goal rests on the surface), but never sets down below the config's ``surface_y`` (the board's top):
a planned sub-goal is a decoded latent, whose bottom can lie 2 cm under its true one, and carrying the
piece that low drove it into the board's edge until the step limit (LiftSpread seed 1000).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from pasta.core import Controller, InputError, Skill, SkillObservation, ToolPose
from pasta.core.shapes import as_points
from pasta_skill_lift.plugin import SPEC, LiftConfig
from pasta_skill_lift.tool import BOARD_POSE, SPATULA, SPATULA_HALF, SPATULA_PARK

STEP = SPATULA.scale("x")  # metres per env step at action 1 (all three channels)
PLATE_TOP = SPATULA_HALF[1]  # the plate's top is this far above its centre


def bottom(points: np.ndarray) -> float:
    """Bottom height of ``points (P, 3)``: the 1st percentile of y."""
    return float(np.percentile(np.asarray(points, np.float64)[:, 1], 1))


def scoop_pose(piece: np.ndarray, scoop_depth: float) -> ToolPose:
    """The plate centred under ``piece (P, 3)``'s centroid, its top ``scoop_depth`` above the piece's bottom."""
    piece = np.asarray(piece, np.float64)
    c = piece.mean(0)
    return ToolPose((float(c[0]), bottom(piece) + scoop_depth - PLATE_TOP, float(c[2])), 0.0)


class LiftController(Controller):
    """Rise, carry the piece's centroid to the target, sink below the surface (see the module doc)."""

    def __init__(self, config: LiftConfig, params: dict[str, float] | None = None) -> None:
        self.cfg = config
        self.params = params
        self.target: np.ndarray | None = None
        self.surface = 0.0
        self.phase = "rise"

    def reset(self, obs: SkillObservation) -> None:
        if self.params is not None:
            self.target = np.array([self.params["target_x"], self.params["target_z"]], np.float64)
            self.surface = float(self.params["surface_y"])
        else:
            if obs.goal is None or len(obs.goal) == 0:
                raise InputError("lift controller: the goal piece is empty")
            goal = np.asarray(obs.goal, np.float64)
            self.target = goal[:, [0, 2]].mean(0)
            self.surface = max(bottom(goal), float(self.cfg.surface_y))
        self.phase = "rise"

    def _speed(self, distance: float) -> float:
        cfg = self.cfg
        return float(min(cfg.speed, max(distance / max(cfg.slow_distance, 1e-9), 0.2) * cfg.speed, distance / STEP))

    def act(self, obs: SkillObservation) -> tuple[np.ndarray, bool]:
        if self.target is None:
            self.reset(obs)
        cfg = self.cfg
        top = float(obs.tool_pose[1]) + PLATE_TOP
        action = np.zeros(3, np.float32)
        if self.phase == "rise":
            rem = self.surface + cfg.clearance - top
            if rem > cfg.tolerance:
                action[1] = self._speed(rem)
                return action, False
            self.phase = "carry"
        if self.phase == "carry":
            rem = self.target - np.asarray(obs.piece, np.float64)[:, [0, 2]].mean(0)
            dist = float(np.linalg.norm(rem))
            if dist > cfg.tolerance:
                v = rem / dist * self._speed(dist)
                action[0], action[2] = v[0], v[1]
                return action, False
            self.phase = "sink"
        rem = top - (self.surface - cfg.sink)
        if rem > cfg.tolerance:
            action[1] = -self._speed(rem)
            return action, False
        return action, True


class LiftSkill(Skill):
    """lift one dough piece with the spatula and set it down on the raised board (1 -> 1, tool: spatula)."""

    spec = SPEC
    sweep_half_width = SPATULA_HALF[2]
    #: the shipped networks' settings (docs/learning.md, "The board skills": near misses made the feasibility
    #: worse; docs/policies.md, "lift and gather": without the goal offset the policy carried every piece the
    #: same way and never stopped; with it, its own done head stops it, so no stopping rule is chosen)
    training_defaults: ClassVar[Mapping[str, Mapping[str, Any]]] = {
        "feasibility": {"stride": 4, "epochs": 8},
        # a plan hands the lift decoded sub-goals (lower, longer, off-centre): half its goals are such (docs/policies.md)
        "policy": {"goal_feature": True, "decoded_goals": 0.5, "decoded_noise": 0.5, "decoded_shift": 0.03},
    }

    def __init__(self, config: LiftConfig | None = None) -> None:
        super().__init__(config if config is not None else LiftConfig())

    @property
    def max_steps(self) -> int:
        return int(self.config.max_steps)

    def approach_pose(self, piece: np.ndarray, goal: np.ndarray | None = None, scene: np.ndarray | None = None) -> ToolPose:
        """The plate slid under ``piece (P, 3)`` (:func:`scoop_pose`); the goal does not change it."""
        return scoop_pose(as_points(piece, "piece"), self.config.scoop_depth)

    def expert_approach_pose(self, piece: np.ndarray, params: dict[str, float], scene: np.ndarray | None = None) -> ToolPose:
        return scoop_pose(as_points(piece, "piece"), self.config.scoop_depth)

    def park_pose(self) -> ToolPose:
        return ToolPose(SPATULA_PARK, 0.0)

    def sample_expert_params(self, piece: np.ndarray, rng: np.random.Generator) -> dict[str, float]:
        """A target centroid uniform in the config's box (on the board) and the config's surface height."""
        cfg = self.config
        return {"target_x": float(rng.uniform(cfg.target_x_min, cfg.target_x_max)),
                "target_z": float(rng.uniform(cfg.target_z_min, cfg.target_z_max)),
                "surface_y": float(cfg.surface_y)}

    def expert(self, params: dict[str, float]) -> Controller:
        missing = {"target_x", "target_z", "surface_y"} - set(params)
        if missing:
            raise InputError(f"lift expert needs parameters target_x, target_z and surface_y; missing {sorted(missing)}")
        return LiftController(self.config, {k: float(params[k]) for k in ("target_x", "target_z", "surface_y")})

    def controller(self) -> Controller:
        return LiftController(self.config)

    def demo_tools(self, variant: str = "default") -> dict[str, ToolPose]:
        """The raised board at its task pose: demonstrations lift onto it, as the tasks do."""
        return {"board": ToolPose(BOARD_POSE, 0.0)}

    def demo_scene(self, rng: np.random.Generator, floor_y: float, variant: str = "default") -> list:
        """A dough cube (side 0.055-0.07) on the floor right of the board (x 0.6-0.75, z 0.4-0.6); the
        board stands at its task pose (:meth:`demo_tools`), so the expert sets the dough down on it."""
        side = float(rng.uniform(0.055, 0.07))
        return [((float(rng.uniform(0.6, 0.75)), floor_y + side / 2, float(rng.uniform(0.4, 0.6))), (side, side, side))]
