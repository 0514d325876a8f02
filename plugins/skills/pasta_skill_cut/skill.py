"""The 'cut' skill: cut one dough piece in two with the knife.

The knife only translates in x and y (action ``(dx, dy)`` in ``[-1, 1]``, times 0.015 per env step), so
every cut is a plane ``x = const``. One execution has three phases:

1. align: move the knife (approach pose: above the piece centroid) to the cut position ``x``;
2. descend: lower it until the tip is below the piece bottom (a clean cut), lift it out and lower it
   into the cut again (the blade is only ~3 grid cells thick: dough pressed into it during the cut
   would otherwise drag the far piece along);
3. separate: slide it sideways slowly (fast pushes make the dough slide on for a long time), pushing
   one part away, then report done. The heuristic then also pushes the other part to its goal
   centroid (from its near side, or lifting the knife over it to push from the far side).

The scripted expert gets the cut position and the knife travel as explicit parameters; the heuristic
controller infers them from point clouds alone: the cut position is the quantile of the piece's ``x``
at the goal's left-piece point fraction (point counts are volumes, whatever the shapes), and it
separates until the moved part's centroid ``x`` reaches that of its goal piece (and the knife has moved at
least ``min_travel``).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from pasta.core import Controller, DemoVariant, InputError, Skill, SkillObservation, ToolPose
from pasta.core.shapes import as_points
from pasta.demos.scene import crs_box
from pasta_skill_cut.plugin import SPEC, CutConfig
from pasta_skill_cut.tool import KNIFE, KNIFE_HALF, KNIFE_PARK

KNIFE_TIP = KNIFE_HALF[1]  # the blade tip is this far below the knife centre
STEP = KNIFE.scale("x")  # metres per env step at action 1
FAR_LIMITS = (0.05, 0.95)  # knife centre x the simulator lets the knife reach (3 cells from the walls at 64^3)


@dataclass(frozen=True)
class CutPlan:
    """What one cut execution does: cut at ``cut_x``, then separate in ``direction`` (-1: left part
    moves left, +1: right part moves right) until either the knife reaches ``knife_target`` (expert)
    or the moved part's centroid ``x`` reaches ``centroid_target`` (heuristic)."""

    cut_x: float
    direction: int
    knife_target: float | None = None
    centroid_target: float | None = None
    other_target: float | None = None  # heuristic: centroid x the other part should end at
    plane: float | None = None  # heuristic: where the dough should part (cut_x is where the knife goes)


def cell_phase(x: Any, dx: float) -> Any:
    """Where ``x`` (a number or an array) lies in its simulator grid cell of width ``dx``: 0 .. 1."""
    return x / dx - np.floor(x / dx)


def dough_plane(knife_x: float, dx: float, offset: float, slope: float) -> float:
    """Where the dough parts when the knife cuts at ``knife_x`` (measured, see :class:`CutConfig`):
    ``knife_x + dx * (offset + slope * phase)``, ``phase`` the knife's position within its grid cell."""
    phase = cell_phase(knife_x, dx)
    return float(knife_x + dx * (offset + slope * phase))


def knife_candidates(plane: float, dx: float, offset: float, slope: float, min_margin: float = 0.03) -> list[tuple[float, float]]:
    """Every knife ``x`` whose cut parts the dough at ``plane`` (inverse of :func:`dough_plane`), as
    ``(x, phase)``, keeping at least ``min_margin`` of a cell from the cell boundaries (the plane jumps
    there). Within a cell the plane is linear in the knife position; neighbouring cells overlap, so a
    plane can have two solutions."""
    if dx <= 0 or slope == -1.0:
        return []
    out = []
    n0 = int(np.floor(plane / dx))
    for n in range(n0 - 3, n0 + 4):
        x = (plane - offset * dx + slope * n * dx) / (1.0 + slope)
        phase = x / dx - n
        if min_margin <= phase <= 1.0 - min_margin:
            out.append((float(x), float(phase)))
    return out


def knife_x_for_plane(plane: float, dx: float, offset: float, slope: float) -> float:
    """The knife ``x`` whose cut parts the dough at ``plane``: of :func:`knife_candidates` the one
    farthest from a cell boundary (the plane itself when the model is off or has no solution)."""
    cands = knife_candidates(plane, dx, offset, slope, 0.0)
    if not cands:
        return float(plane)
    return max(cands, key=lambda c: min(c[1], 1.0 - c[1]))[0]


def knife_x_for_cut(plane: float, phase: float, dx: float, offset: float, slope: float, plane_sigma: float,
                    phase_sigma: float, min_margin: float = 0.03) -> float:
    """The knife ``x`` whose modelled cut (:func:`dough_plane`) best matches both a ``plane`` and a cell
    ``phase``: the minimum of ``((plane(x) - plane) / plane_sigma)^2 + ((phase(x) - phase) / phase_sigma)^2``
    over knife positions within 3 cells, on a 1/200-cell grid, at least ``min_margin`` of a cell from a
    cell boundary. Each phase has one knife position per plane, so a phase picks between the two
    positions that part the dough at one plane, and a plane slightly off the predicted one is accepted
    when its phase fits far better."""
    if dx <= 0:
        return float(plane)
    xs = plane + dx * np.arange(-600, 601) / 200.0
    ph = cell_phase(xs, dx)
    cost = ((xs + dx * (offset + slope * ph) - plane) / plane_sigma) ** 2 + ((ph - phase) / phase_sigma) ** 2
    cost[(ph < min_margin) | (ph > 1.0 - min_margin)] = np.inf
    return float(xs[int(np.argmin(cost))])


def split_by_x_gap(points: np.ndarray, min_fraction: float = 0.05) -> float:
    """The ``x`` of the widest gap between two parts of ``points (P, 3)``, each keeping at least
    ``min_fraction`` of the points (a cut is always a plane ``x = const``)."""
    xs = np.sort(np.asarray(points, np.float64)[:, 0])
    n = len(xs)
    lo = max(1, int(np.ceil(min_fraction * n)))
    hi = min(n - 1, n - lo)
    if hi <= lo:
        return float(np.median(xs))
    gaps = xs[lo:hi + 1] - xs[lo - 1:hi]
    i = int(np.argmax(gaps)) + lo
    return float(0.5 * (xs[i - 1] + xs[i]))


def plan_from_goal(piece: np.ndarray, goal: np.ndarray, config: CutConfig | None = None) -> CutPlan:
    """Infer the cut from the observed ``piece (P, 3)`` and the two goal pieces ``goal (G, 3)``: the dough
    should part at the quantile of the piece's ``x`` given by the goal's left-piece point fraction; with a
    ``config`` the knife goes where its measured cut model (:func:`knife_x_for_plane`) parts the dough
    there, without one it goes to the plane itself."""
    piece = np.asarray(piece, np.float64)
    goal = np.asarray(goal, np.float64)
    split = split_by_x_gap(goal)
    g_left, g_right = goal[goal[:, 0] < split], goal[goal[:, 0] >= split]
    frac = len(g_left) / len(goal)
    cut_x = float(np.quantile(piece[:, 0], frac))
    p_left, p_right = piece[piece[:, 0] < cut_x], piece[piece[:, 0] >= cut_x]
    d_left = g_left[:, 0].mean() - p_left[:, 0].mean() if len(p_left) else 0.0
    d_right = g_right[:, 0].mean() - p_right[:, 0].mean() if len(p_right) else 0.0
    left_c, right_c = float(g_left[:, 0].mean()), float(g_right[:, 0].mean())
    knife_x = cut_x
    if config is not None and config.grid_dx > 0:
        model = (config.grid_dx, config.plane_offset, config.plane_slope)
        knife_x = knife_x_for_plane(cut_x, *model)
        cands = knife_candidates(cut_x, *model, min_margin=0.03)
        if len(cands) > 1 and -d_left >= d_right and len(p_right):
            # two knife positions part the dough there; they squeeze the part that stays differently
            # (its far end moves right by stay_end_offset + stay_end_slope * phase): match the goal's
            move = float(np.percentile(g_right[:, 0], 99.5) - np.percentile(p_right[:, 0], 99.5))
            knife_x = min(cands, key=lambda c: abs(config.stay_end_offset + config.stay_end_slope * c[1] - move))[0]
    if -d_left >= d_right:
        return CutPlan(knife_x, -1, centroid_target=left_c, other_target=right_c, plane=cut_x)
    return CutPlan(knife_x, +1, centroid_target=right_c, other_target=left_c, plane=cut_x)


class CutController(Controller):
    """Align, descend, lift, re-enter, separate. Built from explicit parameters (expert) or from the goal
    (heuristic)."""

    def __init__(self, config: CutConfig, params: dict[str, float] | None = None) -> None:
        self.cfg = config
        self.params = params
        self.plan: CutPlan | None = None
        self.phase = "align"
        self.bottom = self.top = 0.0
        self.last_y: float | None = None

    def reset(self, obs: SkillObservation) -> None:
        piece = np.asarray(obs.piece, np.float64)
        if self.params is not None:
            cut_x, shift = float(self.params["cut_x"]), float(self.params["shift"])
            direction = -1 if shift < 0 else 1
            self.plan = CutPlan(cut_x, direction, knife_target=cut_x + shift)
        else:
            if obs.goal is None or len(obs.goal) < 2:
                raise InputError("cut controller: the goal must hold the two produced pieces")
            self.plan = plan_from_goal(piece, obs.goal, self.cfg)
        self.bottom = float(np.percentile(piece[:, 1], 1))
        self.top = float(np.percentile(piece[:, 1], 99))
        self.phase = "align"
        self.last_y = None

    def _vertical(self, y: float, target: float, next_phase: str) -> np.ndarray | None:
        """Move towards ``target`` height; None (and switch phase) when there or blocked by the bound."""
        err = target - y
        stalled = self.last_y is not None and abs(self.last_y - y) < 1e-5
        self.last_y = y
        if abs(err) > 1e-4 and not stalled:
            return np.array([0.0, np.clip(err / STEP, -1, 1)], np.float32)
        self.phase, self.last_y = next_phase, None
        return None

    def act(self, obs: SkillObservation) -> tuple[np.ndarray, bool]:
        if self.plan is None:
            self.reset(obs)
        plan, cfg = self.plan, self.cfg
        assert plan is not None  # reset() makes it
        x, y = float(obs.tool_pose[0]), float(obs.tool_pose[1])
        low = self.bottom - cfg.tip_depth + KNIFE_TIP
        high = self.top + cfg.clearance + KNIFE_TIP
        if self.phase == "align":
            err = plan.cut_x - x
            if abs(err) > 1e-4:
                return np.array([np.clip(err / STEP, -1, 1), 0.0], np.float32), False
            self.phase = "descend"
        # cut down, pull the blade out (it releases dough pressed into it) and re-enter the cut: a blade
        # only three grid cells thick otherwise drags the far piece along while separating
        for phase, target, nxt in (("descend", low, "lift"), ("lift", high, "reenter"), ("reenter", low, "separate")):
            if self.phase == phase:
                action = self._vertical(y, target, nxt)
                if action is not None:
                    return action, False
        if self.phase == "done":
            return np.zeros(2, np.float32), True
        if self.phase.startswith("fix"):
            return self._fix_other(obs, x, y)
        # separate
        if plan.knife_target is not None:
            remaining = (plan.knife_target - x) * plan.direction
            allowance = 0.0
        else:
            piece = np.asarray(obs.piece, np.float64)
            moved = piece[(piece[:, 0] - x) * plan.direction > 0]
            if len(moved) == 0:
                return np.zeros(2, np.float32), True
            remaining = (plan.centroid_target - moved[:, 0].mean()) * plan.direction
            allowance = cfg.slide_allowance
            # travel at least min_travel: parts that barely separate are seen as one piece afterwards
            travel_left = cfg.min_travel - (x - plan.cut_x) * plan.direction
            remaining = max(remaining, travel_left + allowance)
        if remaining <= cfg.tolerance + allowance:
            if plan.other_target is None:
                self.phase = "done"
                return np.zeros(2, np.float32), True
            self.phase = "fix"
            return self._fix_other(obs, x, y)
        speed = float(np.clip(remaining / max(cfg.slow_distance, 1e-6), 0.3, 1.0)) * cfg.separate_speed
        if plan.knife_target is not None:
            speed = min(speed, remaining / STEP)  # land exactly on the knife target
        return np.array([plan.direction * speed, 0.0], np.float32), False


    @staticmethod
    def _far_x(other: np.ndarray, away: int) -> float:
        """Knife x just beyond the far end of ``other`` (the part lies on side ``away`` of the knife)."""
        if away > 0:
            return float(np.percentile(other[:, 0], 99.5)) + KNIFE_HALF[0] + 0.01
        return float(np.percentile(other[:, 0], 0.5)) - KNIFE_HALF[0] - 0.01

    def _fix_other(self, obs: SkillObservation, x: float, y: float) -> tuple[np.ndarray, bool]:
        """Heuristic only: push the part that stayed to its goal centroid too (the knife may have dragged
        it, or the re-entry pushed it). From its near side when it must move away from the knife, else
        lift the knife over it, lower it on its far side and push back."""
        plan, cfg = self.plan, self.cfg
        assert plan is not None  # (act() made it)
        piece = np.asarray(obs.piece, np.float64)
        if self.phase == "fix":
            self.side_x = x
            self.phase = "fix_push"
        other = piece[(piece[:, 0] - self.side_x) * plan.direction < 0]
        if len(other) == 0:
            self.phase = "done"
            return np.zeros(2, np.float32), True
        err = plan.other_target - other[:, 0].mean()
        away = -plan.direction  # the other part lies on this side of the knife
        low = self.bottom - cfg.tip_depth + KNIFE_TIP
        high = self.top + cfg.clearance + KNIFE_TIP
        if self.phase == "fix_push":
            if abs(err) <= cfg.fix_tolerance:
                self.phase = "done"
                return np.zeros(2, np.float32), True
            if np.sign(err) == away or not cfg.fix_far_side:
                if np.sign(err) != away:
                    self.phase = "done"
                    return np.zeros(2, np.float32), True
                speed = float(np.clip(abs(err) / max(cfg.slow_distance, 1e-6), 0.3, 1.0)) * cfg.separate_speed
                self.fix_dir = away
                self.phase = "fix_pushing"
                return np.array([away * speed, 0.0], np.float32), False
            far = self._far_x(other, away)
            if not FAR_LIMITS[0] <= far <= FAR_LIMITS[1]:  # no room for the blade beyond the part
                self.phase = "done"
                return np.zeros(2, np.float32), True
            self.phase, self.last_y = "fix_lift", None
        if self.phase == "fix_pushing":
            if err * self.fix_dir <= cfg.tolerance + cfg.slide_allowance:
                self.phase = "done"
                return np.zeros(2, np.float32), True
            speed = float(np.clip(abs(err) / max(cfg.slow_distance, 1e-6), 0.3, 1.0)) * cfg.separate_speed
            return np.array([self.fix_dir * speed, 0.0], np.float32), False
        if self.phase == "fix_lift":
            action = self._vertical(y, high, "fix_over")
            if action is not None:
                return action, False
        if self.phase == "fix_over":
            d = self._far_x(other, away) - x
            if abs(d) > 1e-4:
                return np.array([np.clip(d / STEP, -1, 1), 0.0], np.float32), False
            self.phase, self.last_y = "fix_lower", None
        if self.phase == "fix_lower":
            action = self._vertical(y, low, "fix_back")
            if action is not None:
                return action, False
            self.fix_dir = -away
            self.phase = "fix_pushing"
            return self._fix_other(obs, x, y)
        return np.zeros(2, np.float32), True


class CutSkill(Skill):
    """cut one dough piece in two with the knife (1 -> 2 entities, tool: knife)."""

    spec = SPEC
    #: config fields only the heuristic controller and the learned reset pose read, never the expert
    #: (left out of task cache keys)
    heuristic_fields: tuple[str, ...] = ("max_steps", "slide_allowance", "min_travel", "fix_tolerance", "fix_far_side",
                                         "grid_dx", "plane_offset", "plane_slope", "stay_end_offset", "stay_end_slope",
                                         "reset_plane_sigma", "reset_phase_sigma")
    #: `pasta pipeline` settings (docs/learning.md, docs/policies.md): the feasibility also learns from near
    #: misses that move one of the two halves 3-25 cm (a cut leaves its halves side by side); the policy sees
    #: the execution step and the tool pose and learns from its reset pose on (the align phase, which the
    #: learned reset pose replaces, dropped from the demos); a learned reset pose (stage reset: the plane
    #: and the knife's cell phase, goal pieces' point shares as an input, half the goal pieces decoded
    #: from noisy shape codes; docs/policies.md, "The cut's reset pose and the grid cell"; the plane as the
    #: share of the piece's points left of it, ``x_share``: "crs_twice with learned policies: the fix"); the
    #: stopping-rule grid (select)
    #: ``long``: the cuts crs_twice asks first (0.20-0.24 from the end of a 0.34-0.35 dough, travel 0.10-0.12),
    #: beyond the default demos' 0.20 and 0.08: a learned reset pose trained without them puts that plane
    #: 6-33 mm short (docs/policies.md, "crs_twice with learned policies")
    #: Only the reset pose learns from them (``stages``): the policy, its feasibility and the planner's
    #: networks stay as trained on the default demos.
    demo_variants: ClassVar[Mapping[str, DemoVariant]] = {"long": DemoVariant(config={"offset_max": 0.25, "shift_max": 0.12}, pipeline_demos=150,
                                         stages=("reset",),
                                         description="a 0.3-0.35 long dough cut up to 0.25 from its end, the knife "
                                                     "travelling up to 0.12 (for the learned reset pose only)")}
    training_defaults: ClassVar[Mapping[str, Mapping[str, Any]]] = {
        "feasibility": {"stride": 3, "shift_per_positive": 5, "shift_entities": "one", "shift_max": 0.25},
        "policy": {"start_at_reset": True},
        "reset": {},  # the reset stage runs for the cut, with the trainer's defaults (the shipped regressor's)
        "select": {"thresholds": "0.3,0.4,0.5,0.6,0.7", "max_steps": "0,40,45,50,55,60,65,70,80,100"},
    }

    def __init__(self, config: CutConfig | None = None) -> None:
        super().__init__(config if config is not None else CutConfig())

    @property
    def max_steps(self) -> int:
        return int(self.config.max_steps)

    def approach_pose(self, piece: np.ndarray, goal: np.ndarray | None = None, scene: np.ndarray | None = None) -> ToolPose:
        """Knife above the piece centroid, its tip ``clearance`` above the piece top."""
        piece = as_points(piece, "piece")
        c = piece.mean(0)
        top = float(np.percentile(piece[:, 1], 99))
        return ToolPose((float(c[0]), top + KNIFE_TIP + self.config.clearance, float(c[2])), 0.0)

    def reset_target(self, tool_x: float) -> tuple[float, ...]:
        """``(plane, phase)``: where the dough parts when the knife cuts at ``tool_x`` (the measured cut
        model, :func:`dough_plane`) and where ``tool_x`` lies in its grid cell. A learned reset pose
        regresses these instead of the knife ``x``, which is two-valued for one plane and jumps by two
        cells across a cell boundary (docs/policies.md, "The cut's reset pose and the grid cell"); the
        goal shows the plane (the pieces' point fractions) and the phase (how far the cut squeezed the
        part that stays, ``stay_end_*``)."""
        cfg = self.config
        if cfg.grid_dx <= 0:
            return (float(tool_x), 0.0)
        plane = dough_plane(float(tool_x), cfg.grid_dx, cfg.plane_offset, cfg.plane_slope)
        return (plane, float(cell_phase(float(tool_x), cfg.grid_dx)))

    def reset_tool_x(self, target: Sequence[float]) -> float:
        """The knife ``x`` for a regressed ``(plane, phase)`` (:func:`knife_x_for_cut`); for a plane alone,
        :func:`knife_x_for_plane`."""
        cfg = self.config
        if cfg.grid_dx <= 0:
            return float(target[0])
        model = (cfg.grid_dx, cfg.plane_offset, cfg.plane_slope)
        if len(target) < 2:
            return knife_x_for_plane(float(target[0]), *model)
        return knife_x_for_cut(float(target[0]), float(target[1]), *model, cfg.reset_plane_sigma, cfg.reset_phase_sigma)

    def expert_approach_pose(self, piece: np.ndarray, params: dict[str, float], scene: np.ndarray | None = None) -> ToolPose:
        """The expert starts where every cut starts: above the piece centroid."""
        return self.approach_pose(piece)

    def park_pose(self) -> ToolPose:
        return ToolPose(KNIFE_PARK, 0.0)

    def sample_expert_params(self, piece: np.ndarray, rng: np.random.Generator) -> dict[str, float]:
        """``cut_x``: the piece's left end + U(offset_min, offset_max) (both parts keep >= offset_min);
        ``shift``: -U(shift_min, shift_max), the knife travel pushing the left part away."""
        piece = as_points(piece, "piece")
        cfg = self.config
        left, right = np.percentile(piece[:, 0], [0.5, 99.5])
        hi = min(cfg.offset_max, (right - left) - cfg.offset_min)
        offset = rng.uniform(cfg.offset_min, max(hi, cfg.offset_min))
        return {"cut_x": float(left + offset), "shift": float(-rng.uniform(cfg.shift_min, cfg.shift_max))}

    def expert(self, params: dict[str, float]) -> Controller:
        missing = {"cut_x", "shift"} - set(params)
        if missing:
            raise InputError(f"cut expert needs parameters cut_x and shift; missing {sorted(missing)}")
        return CutController(self.config, dict(params))

    def controller(self) -> Controller:
        return CutController(self.config)

    def demo_scene(self, rng: np.random.Generator, floor_y: float, variant: str = "default") -> list:
        """The CRS dough (:func:`pasta.demos.scene.crs_box`): one long box at the right of the workspace,
        0.2-0.35 long (``long``: 0.3-0.35)."""
        return [crs_box(rng, floor_y, length=(0.3, 0.35))] if variant == "long" else [crs_box(rng, floor_y)]
