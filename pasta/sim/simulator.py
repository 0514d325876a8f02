"""The public simulator: scenes of dough particles, three rigid tools, env steps, state I/O."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np

from pasta.core.errors import ConfigError, InputError, SimulationError

from .config import RUNTIME_PARAMS, SimConfig, check_params
from .tools import (
    PARK_POSES,
    ROLLER_RADIUS,
    TOOL_ACTION_DIMS,
    TOOL_ACTION_SCALES,
    TOOL_NAMES,
    tool_bounds,
    tool_quat,
    tool_surface_points,
)

#: floor height (y) where resting dough bottoms sit, as a fraction of dx (0.02 at the 64^3 grid)
FLOOR_DX = 1.28


class SimulationDiverged(SimulationError):
    """NaN/inf, a particle faster than one cell per substep, or a particle outside the unit cube."""


@dataclass
class Observation:
    """What a policy or planner sees after an env step.

    dough:       (P, 3) float32 positions of a fixed random subset of the particles
    dough_index: (P,) int64 particle indices of that subset (fixed from reset / set_state on)
    tool_poses:  {name: (7,) float32} position + quaternion (w, x, y, z), for every tool
    tool_points: {name: (T, 3) float32} ~100 surface points per tool at its current pose
    step:        env steps since reset
    """

    dough: np.ndarray
    dough_index: np.ndarray
    tool_poses: dict[str, np.ndarray]
    tool_points: dict[str, np.ndarray]
    step: int = 0


@dataclass
class SimState:
    """Full simulator state as plain numpy arrays (N particles, K = len(TOOL_NAMES) tools).

    x, v: (N, 3) float32; F, C: (N, 3, 3) float32; tools: (K, 5) float64 rows of
    (x, y, z, yaw, spin) in TOOL_NAMES order; obs_index: (P,) int64; step: int.
    """

    x: np.ndarray
    v: np.ndarray
    F: np.ndarray
    C: np.ndarray
    tools: np.ndarray
    obs_index: np.ndarray
    step: int = 0
    _fields: ClassVar[tuple[str, ...]] = ("x", "v", "F", "C", "tools", "obs_index")

    def copy(self) -> SimState:
        return SimState(*(getattr(self, k).copy() for k in self._fields), step=self.step)

    def save(self, path: str | Path) -> None:
        """Write an .npz (no pickle)."""
        arrays = {k: np.asarray(getattr(self, k)) for k in self._fields}
        np.savez(path, step=np.int64(self.step), tool_names=np.array(TOOL_NAMES), **arrays)

    @classmethod
    def load(cls, path: str | Path) -> SimState:
        with np.load(path, allow_pickle=False) as z:
            names = tuple(str(s) for s in z["tool_names"])
            if names != TOOL_NAMES:
                raise InputError(f"{path}: saved tools {names} differ from this version's {TOOL_NAMES}")
            return cls(
                x=z["x"].astype(np.float32), v=z["v"].astype(np.float32), F=z["F"].astype(np.float32),
                C=z["C"].astype(np.float32), tools=z["tools"].astype(np.float64),
                obs_index=z["obs_index"].astype(np.int64), step=int(z["step"]),
            )


_ENGINES: dict = {}


def _get_engine(cfg: SimConfig):
    from .engine import Engine, ensure_taichi

    ensure_taichi(cfg.arch, cfg.cpu_threads)
    scatter = "serial" if cfg.arch == "cpu" else "atomic"
    key = (cfg.n_grid, cfg.max_particles, scatter)
    if key not in _ENGINES:
        _ENGINES[key] = Engine(cfg.n_grid, cfg.max_particles, scatter=scatter)
    return _ENGINES[key]


class Simulator:
    """MLS-MPM dough with a knife, a pusher and a roller. See docs/simulator.md.

    Several Simulators with the same (n_grid, max_particles) share one set of Taichi fields and
    kernels (no recompile); their states are swapped in and out transparently when used in turn.
    """

    def __init__(self, cfg: SimConfig | None = None, seed: int | None = None) -> None:
        self.cfg = cfg = cfg if cfg is not None else SimConfig()
        if not isinstance(cfg, SimConfig):
            raise ConfigError(f"Simulator needs a SimConfig, got {type(cfg).__name__}")
        self.seed = cfg.seed if seed is None else int(seed)
        self._params = {k: float(getattr(cfg, k)) for k in RUNTIME_PARAMS}
        self._eng = _get_engine(cfg)
        self.dx = 1.0 / cfg.n_grid
        self.floor_y = FLOOR_DX * self.dx
        self._tools = {name: self._park_pose(name) for name in TOOL_NAMES}
        self._obs_index = np.zeros(0, dtype=np.int64)
        self._step = 0
        self._n = 0
        self._stash: SimState | None = None
        self._activate()

    # ------------------------------------------------------------------ engine sharing
    def _activate(self) -> None:
        eng = self._eng
        if eng.owner is self:
            return
        prev = eng.owner
        if prev is not None and prev._n > 0:
            prev._stash = prev._read_state()
        eng.owner = self
        self._write_params()
        if self._stash is not None:
            self._write_particles(self._stash)
            self._stash = None
        else:
            eng.n_p[None] = 0
            eng.clear_all()

    def _write_params(self) -> None:
        from . import engine as E

        p = self._params
        mu = p["E"] / (2.0 * (1.0 + p["nu"]))
        lam = p["E"] * p["nu"] / ((1.0 + p["nu"]) * (1.0 - 2.0 * p["nu"]))
        arr = np.zeros(E.N_PARAMS, dtype=np.float32)
        arr[E.P_DT], arr[E.P_MU], arr[E.P_LAM], arr[E.P_YIELD] = p["dt"], mu, lam, p["yield_stress"]
        arr[E.P_GRAVITY], arr[E.P_GROUND_FRIC], arr[E.P_SPREAD_FRIC] = p["gravity"], p["ground_friction"], p["spread_friction"]
        arr[E.P_SPREAD_X0], arr[E.P_SPREAD_X1], arr[E.P_SOFTNESS] = p["spread_x_min"], p["spread_x_max"], p["softness"]
        for i, name in enumerate(TOOL_NAMES):
            arr[E.P_TOOL_FRIC0 + i] = p[f"{name}_friction"]
        self._eng.params.from_numpy(arr)

    # ------------------------------------------------------------------ setup
    def _park_pose(self, name: str) -> np.ndarray:
        return np.array([*PARK_POSES[name], 0.0, 0.0], dtype=np.float64)

    def set_params(self, **params: float) -> None:
        """Change runtime parameters (names in ``RUNTIME_PARAMS``: dt, E, nu, yield_stress, gravity,
        ground_friction, spread_friction, spread_x_min, spread_x_max, softness, knife_friction,
        pusher_friction, roller_friction). No recompile."""
        check_params(params)
        self._params.update({k: float(v) for k, v in params.items()})
        if self._eng.owner is self:
            self._write_params()
        else:
            self._activate()

    @property
    def params(self) -> dict[str, float]:
        return dict(self._params)

    def reset(self, particles: np.ndarray, seed: int | None = None) -> Observation:
        """Start a scene: particles (N, 3) with 1 <= N <= max_particles inside the unit cube;
        velocities 0, F = I, every tool parked, step counter 0. The observed subset is drawn from
        ``seed`` (default: the simulator's seed). Returns the first observation."""
        x = np.asarray(particles, dtype=np.float64)
        if x.ndim != 2 or x.shape[1] != 3:
            raise InputError(f"particles must have shape (N, 3), got {x.shape}")
        n = x.shape[0]
        if not 1 <= n <= self.cfg.max_particles:
            raise InputError(f"particles: N={n} must be in [1, max_particles={self.cfg.max_particles}]")
        if not np.isfinite(x).all():
            raise InputError("particles contain NaN or inf")
        lo, hi = 2 * self.dx, 1.0 - 3 * self.dx
        if (x < 0).any() or (x > 1).any():
            raise InputError(f"particles must lie inside the unit cube (and best inside [{lo:.3f}, {hi:.3f}])")
        x = np.clip(x, [lo, self.dx, lo], hi)
        rng = np.random.default_rng(self.seed if seed is None else seed)
        p = self.cfg.obs_points
        idx = rng.choice(n, size=p, replace=n < p)
        if n >= p:
            idx = np.sort(idx)
        st = SimState(
            x=x.astype(np.float32), v=np.zeros((n, 3), np.float32),
            F=np.tile(np.eye(3, dtype=np.float32), (n, 1, 1)), C=np.zeros((n, 3, 3), np.float32),
            tools=np.stack([self._park_pose(name) for name in TOOL_NAMES]), obs_index=idx.astype(np.int64), step=0,
        )
        self.set_state(st)
        return self.observe()

    # ------------------------------------------------------------------ state
    def _read_state(self) -> SimState:
        x, v, F, C = self._eng.get_particles()
        return SimState(x=x, v=v, F=F, C=C, tools=np.stack([self._tools[k] for k in TOOL_NAMES]),
                        obs_index=self._obs_index.copy(), step=self._step)

    def _write_particles(self, st: SimState) -> None:
        self._eng.set_particles(st.x, st.v, st.F, st.C)

    def get_state(self) -> SimState:
        """A deep copy of the full state (restoring it with set_state reproduces runs bitwise)."""
        self._need_scene()
        self._activate()
        return self._read_state()

    def set_state(self, state: SimState) -> None:
        n = state.x.shape[0]
        if not 1 <= n <= self.cfg.max_particles:
            raise InputError(f"state has N={n} particles; must be in [1, max_particles={self.cfg.max_particles}]")
        shapes = {"x": (n, 3), "v": (n, 3), "F": (n, 3, 3), "C": (n, 3, 3), "tools": (len(TOOL_NAMES), 5)}
        for k, shp in shapes.items():
            if np.shape(getattr(state, k)) != shp:
                raise InputError(f"state.{k} has shape {np.shape(getattr(state, k))}, expected {shp}")
        idx = np.asarray(state.obs_index, dtype=np.int64)
        if idx.ndim != 1 or idx.size == 0 or idx.min() < 0 or idx.max() >= n:
            raise InputError(f"state.obs_index must be a non-empty 1-D array of indices in [0, {n})")
        self._activate()
        self._write_particles(state)
        self._n = n
        self._tools = {k: np.array(state.tools[i], dtype=np.float64) for i, k in enumerate(TOOL_NAMES)}
        self._obs_index = idx.copy()
        self._step = int(state.step)

    def _need_scene(self) -> None:
        if self._n == 0:
            raise SimulationError("no scene loaded: call Simulator.reset(particles) or set_state(state) first")

    @property
    def n_particles(self) -> int:
        return self._n

    @property
    def step_count(self) -> int:
        return self._step

    def particles(self) -> np.ndarray:
        """(N, 3) float32 positions of every particle."""
        self._need_scene()
        self._activate()
        return self._eng.x.to_numpy()[: self._n]

    # ------------------------------------------------------------------ tools
    def _check_tool(self, name: str) -> None:
        if name not in TOOL_NAMES:
            raise InputError(f"unknown tool '{name}'; tools: {', '.join(TOOL_NAMES)}")

    def set_tool_pose(self, name: str, position, yaw: float = 0.0) -> None:
        """Teleport a tool (centre position (3,), yaw about +y in radians). The position is clamped
        to the tool's allowed box (inside the walls; roller axis y >= its radius)."""
        self._check_tool(name)
        pos = np.asarray(position, dtype=np.float64)
        if pos.shape != (3,) or not np.isfinite(pos).all() or not math.isfinite(yaw):
            raise InputError(f"set_tool_pose('{name}'): position must be 3 finite numbers, yaw finite")
        lo, hi = tool_bounds(name, self.dx)
        self._tools[name] = np.array([*np.clip(pos, lo, hi), float(yaw), self._tools[name][4]])

    def park_tool(self, name: str) -> None:
        """Move a tool to its fixed parking pose, high above the workspace (PARK_POSES)."""
        self._check_tool(name)
        self._tools[name] = self._park_pose(name)

    def tool_pose(self, name: str) -> np.ndarray:
        """(7,) float32: position + quaternion (w, x, y, z)."""
        self._check_tool(name)
        t = self._tools[name]
        return np.concatenate([t[:3], tool_quat(t[3], t[4])]).astype(np.float32)

    def tool_yaw(self, name: str) -> float:
        self._check_tool(name)
        return float(self._tools[name][3])

    # ------------------------------------------------------------------ stepping
    def step(self, actions: dict | None = None) -> None:
        """One env step (``substeps`` MPM substeps). ``actions``: {tool name: array in [-1, 1]
        (values are clipped) of length TOOL_ACTION_DIMS[name]}; tools not named stay still.

        knife (dx, dy) x 0.015; pusher (dx, dy, dz, dyaw) x (0.01, 0.01, 0.01, 0.025 rad);
        roller (roll, dyaw, dy, slide) x (0.7 rad, 0.005 rad, 0.005, 0.005), a 3-vector means
        slide = 0. Rolling by angle a moves the roller a * radius perpendicular to its axis.
        Raises SimulationDiverged (the state is then invalid: reset or set_state)."""
        self._need_scene()
        actions = {} if actions is None else actions
        if not isinstance(actions, dict):
            raise InputError(f"actions must be a dict {{tool name: array}}, got {type(actions).__name__}")
        cfg = self.cfg
        dt = self._params["dt"]
        T = cfg.substeps * dt
        from . import engine as E

        tool_arr = np.zeros((len(TOOL_NAMES), E.TS), dtype=np.float32)
        new_tools = {}
        for i, name in enumerate(TOOL_NAMES):
            cur = self._tools[name]
            tool_arr[i, E.TS_POS:E.TS_POS + 3] = cur[:3]
            tool_arr[i, E.TS_YAW] = cur[3]
            new_tools[name] = cur.copy()
        for name, a in actions.items():
            self._check_tool(name)
            a = np.asarray(a, dtype=np.float64).reshape(-1) if np.ndim(a) <= 1 else np.asarray(a)
            dim = TOOL_ACTION_DIMS[name]
            ok_shapes = ((dim,), (3,)) if name == "roller" else ((dim,),)
            if a.shape not in ok_shapes:
                raise InputError(f"action for '{name}' must have shape ({dim},), got {a.shape}")
            if not np.isfinite(a).all():
                raise InputError(f"action for '{name}' contains NaN or inf")
            a = np.clip(a, -1.0, 1.0) * np.asarray(TOOL_ACTION_SCALES[name][: a.shape[0]])
            cur = self._tools[name]
            yaw = cur[3]
            delta = np.zeros(3)
            dyaw = 0.0
            omega = np.zeros(3)
            spin = cur[4]
            if name == "knife":
                delta[:2] = a
            elif name == "pusher":
                delta[:] = a[:3]
                dyaw = a[3]
            else:  # roller
                roll, dyaw, dy = a[0], a[1], a[2]
                slide = a[3] if a.shape[0] == 4 else 0.0
                d = np.array([math.cos(yaw), 0.0, -math.sin(yaw)])  # local +x in world
                axis = np.array([math.sin(yaw), 0.0, math.cos(yaw)])  # local +z in world
                delta = d * (roll * ROLLER_RADIUS + slide) + np.array([0.0, dy, 0.0])
                omega = -roll / T * axis
                spin = spin - roll
            lo, hi = tool_bounds(name, self.dx)
            target = np.clip(cur[:3] + delta, lo, hi)
            omega[1] += dyaw / T
            i = TOOL_NAMES.index(name)
            tool_arr[i, E.TS_VEL:E.TS_VEL + 3] = (target - cur[:3]) / T
            tool_arr[i, E.TS_OMEGA:E.TS_OMEGA + 3] = omega
            tool_arr[i, E.TS_YAWRATE] = dyaw / T
            new_tools[name] = np.array([*target, yaw + dyaw, spin])
        self._activate()
        eng = self._eng
        eng.tool.from_numpy(tool_arr)
        eng.reset_bad()
        eng.substeps(cfg.substeps, dt)
        bad = eng.bad.to_numpy()
        self._tools = new_tools
        self._step += 1
        if bad.any():
            raise SimulationDiverged(
                f"simulation diverged in env step {self._step}: {int(bad[0])} particle updates were non-finite or "
                f"faster than one grid cell per substep and {int(bad[1])} left the unit cube "
                f"(E={self._params['E']:g}, dt={self._params['dt']:g}); lower dt or the stiffness, or the "
                "action; the state is invalid now: call reset() or set_state()"
            )

    def check(self) -> int:
        """Number of particles with a non-finite state or outside the unit cube (a reduction kernel)."""
        self._need_scene()
        self._activate()
        return int(self._eng.check_state())

    # ------------------------------------------------------------------ observation
    def observe(self) -> Observation:
        self._need_scene()
        self._activate()
        x = self._eng.x.to_numpy()
        poses = {k: self.tool_pose(k) for k in TOOL_NAMES}
        points = {k: tool_surface_points(k, self._tools[k][:3], self._tools[k][3], self._tools[k][4]) for k in TOOL_NAMES}
        return Observation(dough=x[self._obs_index].astype(np.float32), dough_index=self._obs_index.copy(),
                           tool_poses=poses, tool_points=points, step=self._step)
