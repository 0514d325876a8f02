"""The public simulator: scenes of dough particles, rigid tools from plugins, env steps, state I/O."""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any, ClassVar

import numpy as np

from pasta.core.errors import ConfigError, InputError, SimulationError
from pasta.core.files import save_with
from pasta.core.tool import ToolSpec

from .config import RUNTIME_PARAMS, SimConfig, check_params
from .tools import STATE_COLS, ToolTable, tool_quat

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
    """Full simulator state as plain numpy arrays (N particles, K tools).

    x, v: (N, 3) float32; F, C: (N, 3, 3) float32; tools: (K, 6) float64 rows of
    (x, y, z, yaw, spin, aperture); obs_index: (P,) int64;
    step: int; tool_names: the K tools' names, row order (empty: the simulator's tool order).
    """

    x: np.ndarray
    v: np.ndarray
    F: np.ndarray
    C: np.ndarray
    tools: np.ndarray
    obs_index: np.ndarray
    step: int = 0
    tool_names: tuple[str, ...] = ()
    _fields: ClassVar[tuple[str, ...]] = ("x", "v", "F", "C", "tools", "obs_index")

    def copy(self) -> SimState:
        return SimState(self.x.copy(), self.v.copy(), self.F.copy(), self.C.copy(), self.tools.copy(),
                        self.obs_index.copy(), step=self.step, tool_names=tuple(self.tool_names))

    def save(self, path: str | Path | IO[bytes]) -> None:
        """Write an .npz (no pickle) to a file object, or whole to a path (:func:`pasta.core.files.save_with`)."""
        # (values typed Any: np.savez's stub checks **kwds against its allow_pickle flag)
        arrays: dict[str, Any] = {k: np.asarray(getattr(self, k)) for k in self._fields}
        names = np.array(list(self.tool_names), dtype=str)
        if isinstance(path, (str, os.PathLike)):
            save_with(path, lambda fh: np.savez(fh, step=np.int64(self.step), tool_names=names, **arrays))
        else:
            np.savez(path, step=np.int64(self.step), tool_names=names, **arrays)

    @classmethod
    def load(cls, path: str | Path | IO[bytes]) -> SimState:
        """Read an .npz of :meth:`save`. A state saved before tools were plugins (no ``tool_names``, five tool
        columns) is refused with one error: replay it with the pasta release that wrote it."""
        with np.load(path, allow_pickle=False) as z:
            tools = z["tools"].astype(np.float64)
            if "tool_names" not in z.files or tools.ndim != 2 or tools.shape[1] != 6:
                raise InputError(f"{path}: a simulator state of an older format (tools {tools.shape}, "
                                 f"{'no ' if 'tool_names' not in z.files else ''}tool names; this pasta reads "
                                 "named (K, 6) tool rows, written since tools became plugins); replay it with the "
                                 "pasta that wrote it")
            names = tuple(str(s) for s in z["tool_names"])
            if len(names) != tools.shape[0]:
                raise InputError(f"{path}: tools has shape {tools.shape}, expected ({len(names)}, 6) for tools {names}")
            return cls(
                x=z["x"].astype(np.float32), v=z["v"].astype(np.float32), F=z["F"].astype(np.float32),
                C=z["C"].astype(np.float32), tools=tools,
                obs_index=z["obs_index"].astype(np.int64), step=int(z["step"]), tool_names=names,
            )


_ENGINES: dict = {}


def _get_engine(cfg: SimConfig):
    from .engine import Engine, ensure_taichi

    ensure_taichi(cfg.arch, cfg.cpu_threads, cfg.fast_math)
    scatter = "serial" if cfg.arch == "cpu" else "atomic"
    key = (cfg.n_grid, cfg.max_particles, scatter)
    if key not in _ENGINES:
        _ENGINES[key] = Engine(cfg.n_grid, cfg.max_particles, scatter=scatter)
    return _ENGINES[key]


class Simulator:
    """MLS-MPM dough with rigid tools. See docs/simulator.md.

    Args:
        cfg: the settings (defaults when ``None``).
        tools: the tools, a sequence of :class:`~pasta.core.ToolSpec` (at most ``MAX_TOOLS``), acting on the
            dough one after the other in this order. The caller chooses them (every registered tool with
            geometry: ``pasta.plugins.get_plugins().simulated_tools()``): the simulator knows no registry.
        seed: seed of the observed particle subset (default ``cfg.seed``).

    Several Simulators with the same (n_grid, max_particles) share one set of Taichi fields and
    kernels (no recompile, whatever their tools); their states are swapped in and out transparently
    when used in turn.
    """

    def __init__(self, cfg: SimConfig | None = None, *, tools: Sequence[ToolSpec], seed: int | None = None) -> None:
        self.cfg = cfg = cfg if cfg is not None else SimConfig()
        if not isinstance(cfg, SimConfig):
            raise ConfigError(f"Simulator needs a SimConfig, got {type(cfg).__name__}")
        self.seed = cfg.seed if seed is None else int(seed)
        self._params = {k: float(getattr(cfg, k)) for k in RUNTIME_PARAMS}
        self.dx = 1.0 / cfg.n_grid
        self._table = ToolTable(list(tools), cfg.tool_friction, self.dx)
        self._eng = _get_engine(cfg)
        self.floor_y = FLOOR_DX * self.dx
        self._tools = {name: self._table.park_row(name) for name in self._table.names}
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
        eng.set_tools(self._table.kernel_arrays())
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
        self._eng.params.from_numpy(arr)

    # ------------------------------------------------------------------ setup
    @property
    def tool_names(self) -> tuple[str, ...]:
        """The simulator's tools, in the order they act (and of ``SimState.tools`` rows)."""
        return self._table.names

    def tool_spec(self, name: str) -> ToolSpec:
        """The :class:`~pasta.core.ToolSpec` of tool ``name``."""
        return self._table.spec(name)

    def set_params(self, **params: float) -> None:
        """Change runtime parameters (names in ``RUNTIME_PARAMS``: dt, E, nu, yield_stress, gravity,
        ground_friction, spread_friction, spread_x_min, spread_x_max, softness; and ``<tool>_friction``
        for each of the simulator's tools, e.g. knife_friction). No recompile."""
        fric = {k: v for k, v in params.items() if k.endswith("_friction") and k[: -len("_friction")] in self._table.specs}
        rest = {k: v for k, v in params.items() if k not in fric}
        check_params(rest)
        for k, v in fric.items():
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(float(v)) or float(v) < 0:
                raise ConfigError(f"{k}={v!r}: must be a finite number >= 0")
        self._params.update({k: float(v) for k, v in rest.items()})
        self._table.friction.update({k[: -len("_friction")]: float(v) for k, v in fric.items()})
        if self._eng.owner is self:
            self._write_params()
            self._eng.set_tools(self._table.kernel_arrays())
        else:
            self._activate()

    @property
    def params(self) -> dict[str, float]:
        """The runtime parameters of ``RUNTIME_PARAMS`` (tool frictions: :attr:`tool_friction`)."""
        return dict(self._params)

    @property
    def tool_friction(self) -> dict[str, float]:
        """{tool name: Coulomb friction in use}."""
        return dict(self._table.friction)

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
            tools=np.stack([self._table.park_row(name) for name in self.tool_names]), obs_index=idx.astype(np.int64),
            step=0, tool_names=self.tool_names,
        )
        self.set_state(st)
        return self.observe()

    # ------------------------------------------------------------------ state
    def _read_state(self) -> SimState:
        x, v, F, C = self._eng.get_particles()
        return SimState(x=x, v=v, F=F, C=C, tools=np.stack([self._tools[k] for k in self.tool_names]),
                        obs_index=self._obs_index.copy(), step=self._step, tool_names=self.tool_names)

    def _write_particles(self, st: SimState) -> None:
        self._eng.set_particles(st.x, st.v, st.F, st.C)

    def get_state(self) -> SimState:
        """A deep copy of the full state (restoring it with set_state reproduces runs bitwise)."""
        self._need_scene()
        self._activate()
        return self._read_state()

    def _state_tools(self, state: SimState) -> dict[str, np.ndarray]:
        """Tool rows of ``state`` by name: rows named in ``state.tool_names`` (tools the state does not
        name are parked), else rows in this simulator's order."""
        tools = np.asarray(state.tools, dtype=np.float64)
        names = tuple(state.tool_names) or self.tool_names
        if tools.ndim != 2 or tools.shape[1] != 6 or tools.shape[0] != len(names):
            raise InputError(f"state.tools has shape {tools.shape}, expected ({len(names)}, 6) for tools {list(names)}")
        unknown = [k for k in names if k not in self._table.specs]
        if unknown:
            raise InputError(f"state has tools {unknown} this simulator does not have; its tools: {', '.join(self.tool_names)}")
        out = {k: self._table.park_row(k) for k in self.tool_names}
        for i, k in enumerate(names):
            out[k][:] = tools[i]
        return out

    def set_state(self, state: SimState) -> None:
        n = state.x.shape[0]
        if not 1 <= n <= self.cfg.max_particles:
            raise InputError(f"state has N={n} particles; must be in [1, max_particles={self.cfg.max_particles}]")
        shapes = {"x": (n, 3), "v": (n, 3), "F": (n, 3, 3), "C": (n, 3, 3)}
        for k, shp in shapes.items():
            if np.shape(getattr(state, k)) != shp:
                raise InputError(f"state.{k} has shape {np.shape(getattr(state, k))}, expected {shp}")
        rows = self._state_tools(state)
        idx = np.asarray(state.obs_index, dtype=np.int64)
        if idx.ndim != 1 or idx.size == 0 or idx.min() < 0 or idx.max() >= n:
            raise InputError(f"state.obs_index must be a non-empty 1-D array of indices in [0, {n})")
        self._activate()
        self._write_particles(state)
        self._n = n
        self._tools = rows
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
        if name not in self._table.specs:
            raise InputError(f"unknown tool '{name}'; tools: {', '.join(self.tool_names)}")

    def set_tool_pose(self, name: str, position, yaw: float = 0.0, aperture: float | None = None) -> None:
        """Teleport a tool (centre position (3,), yaw about +y in radians; a finger pair's ``aperture``,
        default unchanged). The position is clamped to the tool's allowed box (inside the walls, centre
        y >= ``ToolSpec.lowest_centre``), the aperture to the finger pair's range."""
        self._check_tool(name)
        pos = np.asarray(position, dtype=np.float64)
        if pos.shape != (3,) or not np.isfinite(pos).all() or not math.isfinite(yaw):
            raise InputError(f"set_tool_pose('{name}'): position must be 3 finite numbers, yaw finite")
        lo, hi = self._table.bounds(name)
        row = self._tools[name].copy()
        row[:4] = [*np.clip(pos, lo, hi), float(yaw)]
        if aperture is not None:
            if not math.isfinite(aperture):
                raise InputError(f"set_tool_pose('{name}'): aperture must be finite")
            a_lo, a_hi = self._table.aperture_range(name)
            row[5] = min(max(float(aperture), a_lo), a_hi)
        self._tools[name] = row

    def park_tool(self, name: str) -> None:
        """Move a tool to its parking pose (``ToolSpec.park``, yaw 0, starting aperture)."""
        self._check_tool(name)
        self._tools[name] = self._table.park_row(name)

    def tool_pose(self, name: str) -> np.ndarray:
        """(7,) float32: position + quaternion (w, x, y, z)."""
        self._check_tool(name)
        t = self._tools[name]
        return np.concatenate([t[:3], tool_quat(t[3], t[4])]).astype(np.float32)

    def tool_yaw(self, name: str) -> float:
        self._check_tool(name)
        return float(self._tools[name][3])

    def tool_aperture(self, name: str) -> float:
        """The gap between a finger pair's fingers (0 for tools without one)."""
        self._check_tool(name)
        return float(self._tools[name][5])

    def tool_state(self, name: str) -> dict[str, float]:
        """The tool's state row by column name: x, y, z, yaw, spin, aperture."""
        self._check_tool(name)
        return dict(zip(STATE_COLS, (float(v) for v in self._tools[name])))

    # ------------------------------------------------------------------ stepping
    def _action(self, name: str, a) -> np.ndarray:
        """The action of tool ``name`` as a checked float64 vector, clipped to [-1, 1] and scaled."""
        spec = self._table.spec(name)
        a = np.asarray(a, dtype=np.float64).reshape(-1) if np.ndim(a) <= 1 else np.asarray(a)
        dim, req = spec.action_dim, spec.required_action
        if dim == 0:
            raise InputError(f"tool '{name}' is a static obstacle (no action channels); move it with set_tool_pose")
        if a.ndim != 1 or not req <= a.shape[0] <= dim:
            want = f"({dim},)" if req == dim else f"({req},) to ({dim},)"
            raise InputError(f"action for '{name}' ({', '.join(spec.channels)}) must have shape {want}, got {a.shape}")
        if not np.isfinite(a).all():
            raise InputError(f"action for '{name}' contains NaN or inf")
        return np.clip(a, -1.0, 1.0) * np.asarray(spec.action_scales[: a.shape[0]])

    def step(self, actions: dict | None = None) -> None:
        """One env step (``substeps`` MPM substeps). ``actions``: {tool name: array in [-1, 1] (values are
        clipped), one component per channel of the tool's ``ToolSpec.action``, the optional trailing
        ones may be left out (= 0)}; tools not named stay still.

        Channels (times the channel's scale): see :meth:`ToolTable.motion`. The tool moves at constant
        velocity over the env step.
        Raises SimulationDiverged (the state is then invalid: reset or set_state)."""
        self._need_scene()
        actions = {} if actions is None else actions
        if not isinstance(actions, dict):
            raise InputError(f"actions must be a dict {{tool name: array}}, got {type(actions).__name__}")
        cfg = self.cfg
        dt = self._params["dt"]
        T = cfg.substeps * dt
        from . import engine as E

        tool_arr = np.zeros((E.MAX_TOOLS, E.TS), dtype=np.float32)
        new_tools = {}
        for i, name in enumerate(self.tool_names):
            cur = self._tools[name]
            tool_arr[i, E.TS_POS:E.TS_POS + 3] = cur[:3]
            tool_arr[i, E.TS_YAW] = cur[3]
            tool_arr[i, E.TS_AP] = cur[5]
            new_tools[name] = cur.copy()
        for name, a in actions.items():
            self._check_tool(name)
            vel, omega, yaw_rate, ap_rate, new_tools[name] = self._table.motion(name, self._tools[name],
                                                                                self._action(name, a), T)
            i = self._table.index[name]
            tool_arr[i, E.TS_VEL:E.TS_VEL + 3] = vel
            tool_arr[i, E.TS_OMEGA:E.TS_OMEGA + 3] = omega
            tool_arr[i, E.TS_YAWRATE] = yaw_rate
            tool_arr[i, E.TS_APRATE] = ap_rate
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
        poses = {k: self.tool_pose(k) for k in self.tool_names}
        points = {k: self._table.surface_points(k, self._tools[k]) for k in self.tool_names}
        return Observation(dough=x[self._obs_index].astype(np.float32), dough_index=self._obs_index.copy(),
                           tool_poses=poses, tool_points=points, step=self._step)
