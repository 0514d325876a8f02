"""The pinch skill: the pincer closes on two pieces lying side by side and presses them into one.

Geometry, all in the horizontal (x, z) plane: the *axis* is the line between the two pieces (the main
axis of their points together). The pincer is turned so its fingers close along the axis, centred
on the span of the points along it, fingers low. Closing is the whole motion: ``open`` = -1 per env
step until the gap between the fingers is the target width.

- expert: target width = ``squeeze`` x (the two pieces' summed widths along the axis), with
  ``squeeze`` drawn in [squeeze_min, squeeze_max];
- heuristic controller: target width = the goal piece's width along the axis.

The gap is read from the observed tool points (their span along the axis minus both fingers'
thickness), so the controllers need nothing but a :class:`pasta.core.SkillObservation`.
"""

from __future__ import annotations

import math

import numpy as np

from pasta.core import Controller, InputError, Skill, SkillObservation, ToolPose
from pasta_pinch.plugin import FINGER_HALF, PINCER, SPEC, PinchConfig

OPEN = PINCER.channels.index("open")
ACTION_DIM = PINCER.action_dim
CLOSE_STEP = PINCER.scale("open")


def closing_axis(points: np.ndarray) -> np.ndarray:
    """Unit ``(2,)`` (x, z) direction of the main axis of ``points (P, 3)`` in the horizontal plane."""
    xz = np.asarray(points, np.float64)[:, [0, 2]]
    xz = xz - xz.mean(0)
    _, vecs = np.linalg.eigh(xz.T @ xz)
    axis = vecs[:, -1]
    return axis if axis[0] >= 0 else -axis


def width_along(points: np.ndarray, axis: np.ndarray) -> float:
    """Extent of ``points (P, 3)`` along the horizontal ``axis (2,)`` (1st to 99th percentile)."""
    s = np.asarray(points, np.float64)[:, [0, 2]] @ axis
    lo, hi = np.percentile(s, [1, 99])
    return float(hi - lo)


def finger_gap(tool_points: np.ndarray, axis: np.ndarray) -> float:
    """Current gap between the fingers' inner faces, from the observed tool points ``(T, 3)``."""
    s = np.asarray(tool_points, np.float64)[:, [0, 2]] @ axis
    return float(s.max() - s.min() - 4 * FINGER_HALF[0])


def two_pieces(points: np.ndarray, axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Split ``points (P, 3)`` at the widest gap along ``axis``: the two pieces, in axis order."""
    s = np.asarray(points, np.float64)[:, [0, 2]] @ axis
    order = np.argsort(s)
    cut = int(np.argmax(np.diff(s[order]))) + 1
    return points[order[:cut]], points[order[cut:]]


class PinchController(Controller):
    """Close the fingers until their gap is ``width`` (expert) or the goal piece's width (heuristic)."""

    def __init__(self, config: PinchConfig, squeeze: float | None = None) -> None:
        self.cfg = config
        self.squeeze = squeeze
        self.axis = np.array([1.0, 0.0])
        self.target = 0.0

    def reset(self, obs: SkillObservation) -> None:
        self.axis = closing_axis(obs.piece)
        if self.squeeze is not None:
            a, b = two_pieces(np.asarray(obs.piece), self.axis)
            self.target = self.squeeze * (width_along(a, self.axis) + width_along(b, self.axis))
        else:
            if obs.goal is None or len(obs.goal) == 0:
                raise InputError("pinch controller: the goal piece is empty")
            self.target = width_along(obs.goal, self.axis) + self.cfg.tolerance

    def act(self, obs: SkillObservation) -> tuple[np.ndarray, bool]:
        action = np.zeros(ACTION_DIM, np.float32)
        remaining = finger_gap(obs.tool_points, self.axis) - self.target
        if remaining <= 1e-4:  # the tool points are float32: within 0.1 mm is there
            return action, True
        action[OPEN] = -min(1.0, remaining / CLOSE_STEP)
        return action, False


def approach(piece: np.ndarray, lift: float, floor_y: float) -> ToolPose:
    """Pincer centred on ``piece (P, 3)`` (both pieces) along their axis, fingers closing along it."""
    piece = np.asarray(piece, np.float64)
    axis = closing_axis(piece)
    xz = piece[:, [0, 2]]
    s = xz @ axis
    across = np.array([-axis[1], axis[0]])
    mid = axis * (s.min() + s.max()) / 2 + across * float((xz @ across).mean())
    # the tool's local +x is (cos yaw, -sin yaw) in (x, z): turn it onto the axis
    yaw = math.atan2(-axis[1], axis[0])
    return ToolPose((float(mid[0]), floor_y + lift + FINGER_HALF[1], float(mid[1])), yaw)


class PinchSkill(Skill):
    """squeeze two pieces into one with the pincer (2 -> 1 entities, tool: pincer)."""

    spec = SPEC
    sweep_half_width = FINGER_HALF[2]

    def __init__(self, config: PinchConfig | None = None) -> None:
        super().__init__(config if config is not None else PinchConfig())

    @property
    def max_steps(self) -> int:
        return int(self.config.max_steps)

    # -- demonstrations ------------------------------------------------------------------------
    def demo_scene(self, rng: np.random.Generator, floor_y: float, variant: str = "default") -> list:
        """Two small pieces side by side along x, 3-7 cm apart, in the middle of the workspace."""
        height = 0.06
        sizes = [(rng.uniform(0.05, 0.07), height, rng.uniform(0.06, 0.08)) for _ in range(2)]
        gap = rng.uniform(0.03, 0.07)
        centre_x, z = rng.uniform(0.45, 0.6), rng.uniform(0.4, 0.6)
        span = sizes[0][0] + gap + sizes[1][0]
        left = centre_x - span / 2
        return [((left + sizes[0][0] / 2, floor_y + height / 2, z), sizes[0]),
                ((left + span - sizes[1][0] / 2, floor_y + height / 2, z + rng.uniform(-0.01, 0.01)), sizes[1])]

    def sample_expert_params(self, piece: np.ndarray, rng: np.random.Generator) -> dict[str, float]:
        return {"squeeze": float(rng.uniform(self.config.squeeze_min, self.config.squeeze_max))}

    def expert_approach_pose(self, piece: np.ndarray, params: dict[str, float], scene: np.ndarray | None = None) -> ToolPose:
        return approach(piece, self.config.lift, _floor(piece))

    def expert(self, params: dict[str, float]) -> Controller:
        if "squeeze" not in params:
            raise InputError(f"pinch expert needs the parameter 'squeeze'; got {sorted(params)}")
        return PinchController(self.config, float(params["squeeze"]))

    # -- execution -----------------------------------------------------------------------------
    def approach_pose(self, piece: np.ndarray, goal: np.ndarray, scene: np.ndarray | None = None) -> ToolPose:
        return approach(piece, self.config.lift, _floor(piece))

    def controller(self) -> Controller:
        return PinchController(self.config)

    def park_pose(self) -> ToolPose:
        return ToolPose(PINCER.park, 0.0)


def _floor(piece: np.ndarray) -> float:
    """Height of the floor under ``piece (P, 3)``: its lowest points rest on it."""
    return float(np.percentile(np.asarray(piece, np.float64)[:, 1], 1))
