"""The 'push' skill: push one dough piece to a new place with the pusher.

The pusher is a paddle (0.03 thick along its local x, 0.2 long along its local z) moved by the action
``(dx, dy, dz, dyaw)`` in ``[-1, 1]`` (0.01 per env step, 0.025 rad). The approach pose puts it low, behind
the piece on the side away from the push direction, its face perpendicular to the line from the piece
centroid to the target centroid; where that footprint would touch other dough (a neighbouring piece a
few centimetres away after a cut) it tries faces turned up to 60 degrees from the ideal one (the pusher's
friction drags the piece along a slanted face).

The controller pushes along the line towards the target centroid (correcting sideways drift), slows
down over the last ``slow_distance`` because the dough slides on after the pusher stops, and is done
when the centroid has reached the target along the original push line. The expert gets the target
centroid ``(target_x, target_z)`` as a parameter; the heuristic controller takes the goal piece's
centroid.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from pasta.core import Controller, DemoVariant, InputError, Skill, SkillObservation, ToolPose
from pasta.core.shapes import as_points
from pasta.demos.scene import HEIGHT, small_box
from pasta_skill_push.plugin import SPEC, PushConfig
from pasta_skill_push.tool import PUSHER, PUSHER_HALF, PUSHER_PARK, pusher_bounds

YAW_STEP = PUSHER.scale("yaw")  # radians per env step at dyaw = 1
#: face normals tried at the approach, as rotations (degrees) of the ideal push direction
ANGLES = (0, 10, -10, 20, -20, 30, -30, 45, -45, 60, -60)


def _unit(v: np.ndarray, fallback: tuple[float, float] = (-1.0, 0.0)) -> np.ndarray:
    n = float(np.linalg.norm(v))
    return np.asarray(v, np.float64) / n if n > 1e-9 else np.asarray(fallback, np.float64)


def _rotate(v: np.ndarray, degrees: float) -> np.ndarray:
    a = math.radians(degrees)
    c, s = math.cos(a), math.sin(a)
    return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1]])


def other_dough(piece: np.ndarray, scene: np.ndarray | None, radius: float = 0.006) -> np.ndarray:
    """Points of ``scene (S, 3)`` farther than ``radius`` from every point of ``piece (P, 3)`` -> ``(O, 3)``."""
    if scene is None or len(scene) == 0:
        return np.zeros((0, 3))
    from scipy.spatial import cKDTree

    d, _ = cKDTree(piece).query(np.asarray(scene, np.float64), k=1)
    return np.asarray(scene, np.float64)[d > radius]


def placement(piece: np.ndarray, target_xz: np.ndarray, scene: np.ndarray | None, cfg: PushConfig,
              max_slide: float = 0.0) -> ToolPose:
    """Approach pose of the pusher for pushing ``piece (P, 3)`` towards centroid ``target_xz (2,)``.

    Faces are tried from the ideal one outwards; with ``max_slide`` > 0 each face is also tried with the
    paddle slid along itself by up to ``max_slide`` (as long as it still spans the piece), which often
    clears a neighbouring piece without turning the face away from the push direction."""
    piece = np.asarray(piece, np.float64)
    c = piece[:, [0, 2]].mean(0)
    u = _unit(np.asarray(target_xz, np.float64) - c)
    others = other_dough(piece, scene)[:, [0, 2]]
    y = float(np.percentile(piece[:, 1], 1)) - cfg.sink + PUSHER_HALF[1]
    lo, hi = pusher_bounds(1.0 / 64)
    best, best_clear = None, -np.inf
    slides = [0.0]
    if max_slide > 0:
        slides += [sign * max_slide * k / 2 for k in (1, 2) for sign in (1, -1)]
    candidates = []
    for angle in ANGLES:
        n = _rotate(u, angle)
        t = np.array([-n[1], n[0]])  # along the paddle
        side = np.percentile((piece[:, [0, 2]] - c) @ t, [1, 99])
        for slide in slides:
            if slide and not (slide - PUSHER_HALF[2] + 0.01 <= side[0] and side[1] <= slide + PUSHER_HALF[2] - 0.01):
                continue  # the slid paddle would no longer span the piece
            candidates.append((angle, n, slide))
    for _angle, n, slide in candidates:
        back = -float(np.percentile((piece[:, [0, 2]] - c) @ n, 0.5))
        centre = c - n * (back + PUSHER_HALF[0] + cfg.gap) + np.array([-n[1], n[0]]) * slide
        yaw = math.atan2(-n[1], n[0])
        if not (lo[0] <= centre[0] <= hi[0] and lo[2] <= centre[1] <= hi[2]):
            continue
        if len(others):
            rel = others - centre
            t = np.array([-n[1], n[0]])  # along the paddle
            a_n, a_t = np.abs(rel @ n) - PUSHER_HALF[0], np.abs(rel @ t) - PUSHER_HALF[2]
            clear = float(np.min(np.maximum(a_n, a_t)))  # box distance lower bound (max of the axis gaps)
        else:
            clear = np.inf
        pose = ToolPose((float(centre[0]), y, float(centre[1])), float(yaw))
        if clear >= cfg.clearance:
            return pose
        if clear > best_clear:
            best, best_clear = pose, clear
    if best is None:  # every candidate left the workspace: push from the ideal side, clamped by the simulator
        centre = c - u * (PUSHER_HALF[0] + cfg.gap)
        best = ToolPose((float(centre[0]), y, float(centre[1])), float(math.atan2(-u[1], u[0])))
    return best


class PushController(Controller):
    """Push the piece centroid to ``target`` (expert) or to the goal's centroid (heuristic)."""

    def __init__(self, config: PushConfig, target: tuple[float, float] | None = None) -> None:
        self.cfg = config
        self.fixed_target = None if target is None else np.asarray(target, np.float64)
        self.target: np.ndarray | None = None
        self.direction = np.array([-1.0, 0.0])

    def reset(self, obs: SkillObservation) -> None:
        if self.fixed_target is not None:
            self.target = self.fixed_target
        else:
            if obs.goal is None or len(obs.goal) == 0:
                raise InputError("push controller: the goal piece is empty")
            self.target = np.asarray(obs.goal, np.float64)[:, [0, 2]].mean(0)
        c = np.asarray(obs.piece, np.float64)[:, [0, 2]].mean(0)
        self.direction = _unit(self.target - c)
        self.start = np.asarray(obs.tool_pose, np.float64)[[0, 2]].copy()

    def act(self, obs: SkillObservation) -> tuple[np.ndarray, bool]:
        if self.target is None:
            self.reset(obs)
        cfg = self.cfg
        c = np.asarray(obs.piece, np.float64)[:, [0, 2]].mean(0)
        rem = self.target - c
        along = float(rem @ self.direction)
        if along <= cfg.tolerance:
            return np.zeros(4, np.float32), True
        speed = float(np.clip(along / max(cfg.slow_distance, 1e-6), cfg.min_speed, 1.0))
        lateral = rem - along * self.direction
        # steer back onto the line, never sideways faster than forwards
        steer = lateral / max(float(np.linalg.norm(lateral)), 1e-9) * min(float(np.linalg.norm(lateral)) / 0.02, 1.0)
        move = _unit(self.direction + 0.5 * steer) * speed
        dyaw = 0.0
        if self.fixed_target is None and cfg.align_after > 0:
            # heuristic: an approach that had to turn the face (neighbouring dough) lets the piece slide
            # along it; once clear of the start, turn the face back square to the push line
            pose = np.asarray(obs.tool_pose, np.float64)
            if float((pose[[0, 2]] - self.start) @ self.direction) >= cfg.align_after:
                yaw = 2.0 * math.atan2(pose[5], pose[3])  # pose[3:7]: quaternion (w, x, y, z) of a yaw about +y
                want = math.atan2(-self.direction[1], self.direction[0])
                err = math.remainder(want - yaw, 2.0 * math.pi)
                dyaw = float(np.clip(err / YAW_STEP, -1.0, 1.0)) if abs(err) > 0.02 else 0.0
        return np.array([move[0], 0.0, move[1], dyaw], np.float32), False


class PushSkill(Skill):
    """push one dough piece to a new place with the pusher (1 -> 1 entities, tool: pusher)."""

    spec = SPEC
    sweep_half_width = PUSHER_HALF[2]  # the paddle spans the piece and more, across the push line
    #: config fields only the heuristic controller reads (left out of task cache keys)
    heuristic_fields: tuple[str, ...] = ("max_face_slide", "align_after")
    #: ``scene=wide``: pieces up to 0.25 long anywhere on the right of the workspace, pushed to targets
    #: with x up to 0.7 (the default box ends at 0.32), as cut_rearrange needs
    #: ``scene=nudge``: pieces 0.05-0.2 long anywhere on the table, pushed 4.5-9 cm in any direction: the corrections a
    #: closed loop asks for after a piece slid (the other demonstrations all travel 8 cm or more); policy only
    demo_variants: ClassVar[Mapping[str, DemoVariant]] = {
        "wide": DemoVariant(config={"target_x_max": 0.7}, pipeline_demos=150,
                            description="pieces up to 0.25 long on the right, targets with x up to 0.7"),
        "nudge": DemoVariant(config={"target_x_min": 0.12, "target_x_max": 0.92, "target_z_min": 0.25,
                                     "target_z_max": 0.75, "min_distance": 0.045, "max_distance": 0.09},
                             pipeline_demos=150, stages=("policy",),
                             description="pieces 0.05-0.2 long anywhere on the table, pushed 4.5-9 cm in any direction"),
    }
    #: the policy sees its step count, the tool pose and the goal offset (with these and the wide demonstrations,
    #: 0.96 on held-out wide configs; the one-frame policy of the default demonstrations alone, 0.45)
    training_defaults: ClassVar[Mapping[str, Mapping[str, Any]]] = {
        "feasibility": {"stride": 4, "epochs": 20},
        "policy": {"goal_feature": True},
    }

    def __init__(self, config: PushConfig | None = None) -> None:
        super().__init__(config if config is not None else PushConfig())

    @property
    def max_steps(self) -> int:
        return int(self.config.max_steps)

    def approach_pose(self, piece: np.ndarray, goal: np.ndarray, scene: np.ndarray | None = None) -> ToolPose:
        """Pusher behind ``piece (P, 3)``, facing the goal centroid (``goal (G, 3)``), avoiding other dough in
        ``scene`` (the heuristic may also slide the paddle along its face, ``max_face_slide``)."""
        piece, goal = as_points(piece, "piece"), as_points(goal, "goal")
        return placement(piece, goal[:, [0, 2]].mean(0), scene, self.config, self.config.max_face_slide)

    def expert_approach_pose(self, piece: np.ndarray, params: dict[str, float], scene: np.ndarray | None = None) -> ToolPose:
        return placement(as_points(piece, "piece"), np.array([params["target_x"], params["target_z"]]), scene, self.config)

    def park_pose(self) -> ToolPose:
        return ToolPose(PUSHER_PARK, 0.0)

    def sample_expert_params(self, piece: np.ndarray, rng: np.random.Generator) -> dict[str, float]:
        """A target centroid uniform in the config's box, at least ``min_distance`` from the piece; with
        ``max_distance`` set, at a distance U(min_distance, max_distance) in a uniform direction, inside the box."""
        c = as_points(piece, "piece")[:, [0, 2]].mean(0)
        cfg = self.config
        if cfg.max_distance > 0:
            if cfg.max_distance < cfg.min_distance:
                raise InputError(f"push: max_distance {cfg.max_distance} is below min_distance {cfg.min_distance}")
            for _ in range(1000):
                a, r = rng.uniform(-math.pi, math.pi), rng.uniform(cfg.min_distance, cfg.max_distance)
                t = c + r * np.array([math.cos(a), math.sin(a)])
                if cfg.target_x_min <= t[0] <= cfg.target_x_max and cfg.target_z_min <= t[1] <= cfg.target_z_max:
                    break
            else:
                raise InputError(f"push: no target {cfg.min_distance}-{cfg.max_distance} from the piece at "
                                 f"({c[0]:.3f}, {c[1]:.3f}) lies in the target box")
            return {"target_x": float(t[0]), "target_z": float(t[1])}
        for _ in range(1000):
            t = np.array([rng.uniform(cfg.target_x_min, cfg.target_x_max), rng.uniform(cfg.target_z_min, cfg.target_z_max)])
            if np.linalg.norm(t - c) >= cfg.min_distance:
                break
        return {"target_x": float(t[0]), "target_z": float(t[1])}

    def demo_target(self, dough: np.ndarray, rng: np.random.Generator, variant: str = "default") -> np.ndarray:
        """What demonstrations by trajectory optimisation aim at (``pasta demos skill=push expert=trajopt``, the
        comparison with the scripted expert in docs/learning.md): the piece ``dough (P, 3)`` slid, unchanged, to a
        target centroid drawn as the expert draws its own."""
        piece = as_points(dough, "dough")
        target = self.sample_expert_params(piece, rng)
        shift = np.array([target["target_x"], 0.0, target["target_z"]]) - piece.mean(0) * np.array([1.0, 0.0, 1.0])
        return (piece + shift).astype(np.float32)

    def expert(self, params: dict[str, float]) -> Controller:
        missing = {"target_x", "target_z"} - set(params)
        if missing:
            raise InputError(f"push expert needs parameters target_x and target_z; missing {sorted(missing)}")
        return PushController(self.config, (float(params["target_x"]), float(params["target_z"])))

    def controller(self) -> Controller:
        return PushController(self.config)

    def demo_scene(self, rng: np.random.Generator, floor_y: float, variant: str = "default") -> list:
        """A small piece right of the spreading area (``"wide"``: a piece 0.1-0.25 long with x in 0.4-0.93;
        ``"nudge"``: a piece 0.05-0.2 long with x in 0.15-0.9, z in 0.3-0.7)."""
        if variant == "nudge":
            size = (rng.uniform(0.05, 0.2), HEIGHT, rng.uniform(0.05, 0.1))
            return [((rng.uniform(0.15 + size[0] / 2, 0.9 - size[0] / 2), floor_y + HEIGHT / 2, rng.uniform(0.3, 0.7)), size)]
        if variant == "wide":
            size = (rng.uniform(0.1, 0.25), HEIGHT, rng.uniform(0.06, 0.1))
            x = rng.uniform(0.4, 0.93 - size[0] / 2)
            return [((x, floor_y + HEIGHT / 2, rng.uniform(0.3, 0.7)), size)]
        return [small_box(rng, floor_y, (0.45, 0.7), (0.3, 0.7))]
