"""Gradients through the simulator: the differentiable driver of the MLS-MPM physics (docs/simulator.md,
"Gradients").

:func:`rollout` runs a sequence of env steps on a :class:`~pasta.sim.Simulator`'s current state and returns
the dough particles as a torch tensor that carries gradients back to the tools' actions and initial poses::

    actions = {"knife": torch.zeros(8, 2, requires_grad=True)}       # (T, the tool's channels)
    x = rollout(sim, actions)                                        # (N, 3), the final particles
    chamfer(x, target).backward()                                    # actions["knife"].grad: (8, 2)

How: :class:`GradEngine` keeps the particle state of every substep of **one** env step (x, v, C, F and the
SVD of the trial deformation) in fields with gradients; the rollout keeps only each env step's start state
(checkpoints, 96 bytes a particle a step). The backward pass walks the env steps in reverse: it reloads the
step's checkpoint, re-runs its substeps to rebuild the history, then runs the substeps' adjoints in reverse,
rebuilding each substep's grid before its adjoint (the grid is never stored). Every adjoint kernel is
Taichi's autodiff of the kernels that :func:`pasta.sim.engine.physics` defines for the forward simulator too,
except two written by hand: the SVD's (autodiff through an iterative SVD is slow to compile and inaccurate)
and the grid's momentum-to-velocity step's (autodiff's -mv / m^2 overflows where a stencil barely reaches). On CPU every loop that sums into a shared value is serialized, so a gradient is bitwise reproducible
(on a GPU they are parallel atomics, as the forward simulator's scatter is there).

The forward simulator (:class:`~pasta.sim.engine.Engine`) is untouched by all this: it has no history and no
gradient fields, and a process that never asks for a gradient never compiles these kernels.
"""


import math
from collections.abc import Callable, Mapping, Sequence  # no `from __future__ import annotations`: Taichi reads kernel annotations

import numpy as np
import taichi as ti
import torch

from pasta.core.errors import InputError

from .engine import MAX_TOOLS, P_DT, TS, TS_AP, TS_APRATE, TS_OMEGA, TS_POS, TS_VEL, TS_YAW, TS_YAWRATE, physics
from .simulator import Simulator

#: smallest |s_j^2 - s_i^2| the SVD adjoint divides by (equal singular values: the dough at rest)
SVD_EPS = 1e-6


class GradEngine:
    """History fields and kernels of one env step (``n_sub`` substeps) on an :class:`Engine`'s layout.

    Shares the engine's parameter and static tool fields (what the simulator writes when it activates) and has
    its own tool-state field with a gradient. Built once per (engine, substeps) by :func:`grad_engine`.
    """

    def __init__(self, engine, n_sub: int) -> None:
        S, N, n = int(n_sub), engine.max_particles, engine.n_grid
        self.engine, self.n_sub = engine, S
        f32 = ti.f32
        self.x = ti.Vector.field(3, f32, shape=(S + 1, N), needs_grad=True)
        self.v = ti.Vector.field(3, f32, shape=(S + 1, N), needs_grad=True)
        self.C = ti.Matrix.field(3, 3, f32, shape=(S + 1, N), needs_grad=True)
        self.F = ti.Matrix.field(3, 3, f32, shape=(S + 1, N), needs_grad=True)
        self.A = ti.Matrix.field(3, 3, f32, shape=(S, N), needs_grad=True)
        self.U = ti.Matrix.field(3, 3, f32, shape=(S, N), needs_grad=True)
        self.sig = ti.Vector.field(3, f32, shape=(S, N), needs_grad=True)
        self.V = ti.Matrix.field(3, 3, f32, shape=(S, N), needs_grad=True)
        self.grid = ti.Vector.field(4, f32, shape=(n, n, n), needs_grad=True)  # (m v, m)
        # (v, m): after gravity (level 0), after tool t's contact (level t + 1); one kernel per level
        self.levels = ti.Vector.field(4, f32, shape=(MAX_TOOLS + 1, n, n, n), needs_grad=True)
        self.grid_v = ti.Vector.field(4, f32, shape=(n, n, n), needs_grad=True)  # (v, m) after floor and walls
        self.bbox = ti.field(ti.i32, shape=6)  # the touched nodes of the current substep
        self.box_n = ti.field(ti.i32, shape=())  # how many (an autodiff kernel has nothing outside its loops)
        self.tool = ti.field(f32, shape=(MAX_TOOLS, TS), needs_grad=True)
        self.n_p = ti.field(ti.i32, shape=())

        x, v, C, F, A, U, sig, V = self.x, self.v, self.C, self.F, self.A, self.U, self.sig, self.V
        grid, levels, grid_v, bbox, box_n = self.grid, self.levels, self.grid_v, self.bbox, self.box_n
        tool, n_p = self.tool, self.n_p
        params, bad = engine.params, engine.bad
        phys = physics(n, params, tool, engine.statics, differentiable=True)
        inv_dx = float(n)
        # CPU: loops that sum into shared values run serialized (bitwise reproducible, and the fastest scatter on
        # CPU); GPU: parallel float atomics, as the forward engine's "atomic" scatter (not bitwise reproducible)
        serial = engine.scatter_mode == "serial"

        @ti.kernel
        def load(xs: ti.types.ndarray(), vs: ti.types.ndarray(), Fs: ti.types.ndarray(),  # type: ignore[valid-type]
                 Cs: ti.types.ndarray()):  # type: ignore[valid-type]
            for p in range(n_p[None]):
                for i in ti.static(range(3)):
                    x[0, p][i] = xs[p, i]
                    v[0, p][i] = vs[p, i]
                    for j in ti.static(range(3)):
                        F[0, p][i, j] = Fs[p, i, j]
                        C[0, p][i, j] = Cs[p, i, j]

        @ti.kernel
        def trial_svd(s: ti.i32):
            """The trial deformation's SVD as the forward simulator takes it: warm-started from the previous
            substep's V (at the env step's start from a full SVD of F)."""
            for p in range(n_p[None]):
                Fp = (ti.Matrix.identity(ti.f32, 3) + params[P_DT] * C[s, p]) @ F[s, p]
                Vw = ti.Matrix.identity(ti.f32, 3)
                if s == 0:
                    _U0, _S0, V0 = ti.svd(F[0, p])
                    Vw = V0
                else:
                    Vw = V[s - 1, p]
                Up, Sp, Vp = phys.warm_svd(Fp, Vw)
                U[s, p] = Up
                sig[s, p] = Sp
                V[s, p] = Vp

        @ti.kernel
        def stress(s: ti.i32):
            for p in range(n_p[None]):
                Up = U[s, p]
                Vp = V[s, p]
                sn, _changed = phys.return_map(sig[s, p])
                Fn = phys.compose(Up, sn, Vp)
                F[s + 1, p] = Fn
                A[s, p] = phys.affine(Fn, Up, Vp, sn, C[s, p])

        @ti.kernel
        def box(s: ti.i32):
            """The box of grid nodes substep s's particles touch (the forward kernel's bookkeeping, without the
            scatter)."""
            lo = ti.Vector([n, n, n])
            hi = ti.Vector([-1, -1, -1])
            if ti.static(serial):
                ti.loop_config(serialize=True)
                for p in range(n_p[None]):
                    base = ti.cast(x[s, p] * inv_dx - 0.5, ti.i32)
                    lo = ti.min(lo, base)
                    hi = ti.max(hi, base + 2)
                phys.box_store(bbox, lo, hi)
            else:
                phys.box_store(bbox, lo, hi)  # empty
                for p in range(n_p[None]):
                    phys.box_include(bbox, ti.cast(x[s, p] * inv_dx - 0.5, ti.i32))
            _lo, ext = phys.box_extent(bbox)
            box_n[None] = ext[0] * ext[1] * ext[2]

        @ti.kernel
        def clear_box():
            """Zero the box's grid values and gradients (the grids are all-zero outside the box in use)."""
            for tt in range(box_n[None]):
                lo, ext = phys.box_extent(bbox)
                c = phys.box_node(lo, ext, tt)
                grid[c] = ti.Vector.zero(ti.f32, 4)
                grid.grad[c] = ti.Vector.zero(ti.f32, 4)
                grid_v.grad[c] = ti.Vector.zero(ti.f32, 4)
                for t in ti.static(range(MAX_TOOLS + 1)):
                    levels.grad[t, c[0], c[1], c[2]] = ti.Vector.zero(ti.f32, 4)

        @ti.kernel
        def p2g(s: ti.i32):
            ti.loop_config(serialize=serial)
            for p in range(n_p[None]):
                phys.scatter(grid, x[s, p], v[s, p], A[s, p])

        @ti.kernel
        def grid_start():
            for tt in range(box_n[None]):
                lo, ext = phys.box_extent(bbox)
                c = phys.box_node(lo, ext, tt)
                gv = grid[c]
                if gv[3] > 0:
                    vel = phys.node_start(gv)
                    levels[0, c[0], c[1], c[2]] = ti.Vector([vel[0], vel[1], vel[2], gv[3]])

        @ti.kernel
        def grid_start_adjoint():
            """By hand: autodiff's d(mv / m)/dm = -mv / m^2 overflows at a node a particle's stencil barely
            reaches (m ~ 1e-27); written as -(mv / m) / m it does not."""
            for tt in range(box_n[None]):
                lo, ext = phys.box_extent(bbox)
                c = phys.box_node(lo, ext, tt)
                gv = grid[c]
                if gv[3] > 0:
                    g = levels.grad[0, c[0], c[1], c[2]]
                    u = ti.Vector([gv[0], gv[1], gv[2]]) / gv[3]
                    gu = ti.Vector([g[0], g[1], g[2]]) / gv[3]
                    grid.grad[c] = grid.grad[c] + ti.Vector([gu[0], gu[1], gu[2], g[3] - gu.dot(u)])  # no atomic

        @ti.kernel
        def grid_tool(t: ti.i32, j: ti.i32, t_now: ti.f32):
            """Tool t's contact, from level j to level j + 1 (the tools that can reach the box, in order)."""
            ti.loop_config(serialize=serial)  # the tool's gradient sums over nodes: one order, reproducible
            for tt in range(box_n[None]):
                lo, ext = phys.box_extent(bbox)
                c = phys.box_node(lo, ext, tt)
                gv = levels[j, c[0], c[1], c[2]]
                if gv[3] > 0:
                    vel = phys.node_contact(t, c, ti.Vector([gv[0], gv[1], gv[2]]), t_now)
                    levels[j + 1, c[0], c[1], c[2]] = ti.Vector([vel[0], vel[1], vel[2], gv[3]])

        @ti.kernel
        def grid_end(last: ti.i32):
            for tt in range(box_n[None]):
                lo, ext = phys.box_extent(bbox)
                c = phys.box_node(lo, ext, tt)
                gv = levels[last, c[0], c[1], c[2]]
                if gv[3] > 0:
                    vel = phys.node_bounds(c, ti.Vector([gv[0], gv[1], gv[2]]))
                    grid_v[c] = ti.Vector([vel[0], vel[1], vel[2], gv[3]])

        @ti.kernel
        def g2p(s: ti.i32):
            ti.loop_config(serialize=serial)  # the grid's gradients sum over particles
            for p in range(n_p[None]):
                new_v, new_C = phys.gather(grid_v, x[s, p])
                x[s + 1, p], v[s + 1, p], C[s + 1, p] = phys.advance(x[s, p], new_v, new_C, bad)

        @ti.kernel
        def clear_grads():
            for s, p in x:
                if p < n_p[None]:
                    x.grad[s, p] = ti.Vector.zero(ti.f32, 3)
                    v.grad[s, p] = ti.Vector.zero(ti.f32, 3)
                    C.grad[s, p] = ti.Matrix.zero(ti.f32, 3, 3)
                    F.grad[s, p] = ti.Matrix.zero(ti.f32, 3, 3)
            for s, p in A:
                if p < n_p[None]:
                    A.grad[s, p] = ti.Matrix.zero(ti.f32, 3, 3)
                    U.grad[s, p] = ti.Matrix.zero(ti.f32, 3, 3)
                    V.grad[s, p] = ti.Matrix.zero(ti.f32, 3, 3)
                    sig.grad[s, p] = ti.Vector.zero(ti.f32, 3)
            for t, k in tool:
                tool.grad[t, k] = 0.0

        @ti.kernel
        def seed(s: ti.i32, gx: ti.types.ndarray(), gv: ti.types.ndarray(),  # type: ignore[valid-type]
                 gF: ti.types.ndarray(), gC: ti.types.ndarray()):  # type: ignore[valid-type]
            """Set level s's gradients (the loss's, plus what the later env steps sent back)."""
            for p in range(n_p[None]):
                for i in ti.static(range(3)):
                    x.grad[s, p][i] = gx[p, i]
                    v.grad[s, p][i] = gv[p, i]
                    for j in ti.static(range(3)):
                        F.grad[s, p][i, j] = gF[p, i, j]
                        C.grad[s, p][i, j] = gC[p, i, j]

        @ti.kernel
        def svd_adjoint(s: ti.i32):
            """Trial F = (I + dt C) F = U diag(sig) V^T: from the gradients of U, sig, V to those of C and F
            (the standard SVD adjoint, with 1 / (s_j^2 - s_i^2) clamped at SVD_EPS)."""
            for p in range(n_p[None]):
                Up = U[s, p]
                Vp = V[s, p]
                sp = sig[s, p]
                gU = U.grad[s, p]
                gV = V.grad[s, p]
                gs = sig.grad[s, p]
                Jm = Up.transpose() @ gU
                Km = Vp.transpose() @ gV
                for i, j in ti.static(ti.ndrange(3, 3)):
                    if ti.static(i == j):
                        Jm[i, j] = 0.0
                        Km[i, j] = 0.0
                for i, j in ti.static([(0, 1), (0, 2), (1, 2)]):
                    d = sp[j] * sp[j] - sp[i] * sp[i]  # (j, i) divides by -d: the clamp keeps that
                    if ti.abs(d) < SVD_EPS:
                        d = SVD_EPS if d >= 0 else -SVD_EPS
                    Jm[i, j] = Jm[i, j] / d
                    Km[i, j] = Km[i, j] / d
                    Jm[j, i] = -Jm[j, i] / d
                    Km[j, i] = -Km[j, i] / d
                Sm = ti.Matrix([[sp[0], 0.0, 0.0], [0.0, sp[1], 0.0], [0.0, 0.0, sp[2]]])
                Gm = ti.Matrix([[gs[0], 0.0, 0.0], [0.0, gs[1], 0.0], [0.0, 0.0, gs[2]]])
                gFp = Up @ ((Jm + Jm.transpose()) @ Sm + Gm + Sm @ (Km + Km.transpose())) @ Vp.transpose()
                dt = params[P_DT]
                # a particle's own entries: plain adds (`+=` on a field is an atomic, 10x slower here)
                C.grad[s, p] = C.grad[s, p] + dt * gFp @ F[s, p].transpose()
                F.grad[s, p] = F.grad[s, p] + (ti.Matrix.identity(ti.f32, 3) + dt * C[s, p]).transpose() @ gFp

        @ti.kernel
        def read_level(s: ti.i32, xs: ti.types.ndarray(), vs: ti.types.ndarray(),  # type: ignore[valid-type]
                       Fs: ti.types.ndarray(), Cs: ti.types.ndarray(), grads: ti.i32):  # type: ignore[valid-type]
            """Level s's state (grads=0) or its gradients (grads=1) into numpy arrays."""
            for p in range(n_p[None]):
                xv = x[s, p]
                vv = v[s, p]
                Fv = F[s, p]
                Cv = C[s, p]
                if grads:
                    xv = x.grad[s, p]
                    vv = v.grad[s, p]
                    Fv = F.grad[s, p]
                    Cv = C.grad[s, p]
                for i in ti.static(range(3)):
                    xs[p, i] = xv[i]
                    vs[p, i] = vv[i]
                    for j in ti.static(range(3)):
                        Fs[p, i, j] = Fv[i, j]
                        Cs[p, i, j] = Cv[i, j]

        self._load, self._trial_svd, self._stress, self._p2g, self._g2p = load, trial_svd, stress, p2g, g2p
        self._box, self._clear_box, self._clear_grads = box, clear_box, clear_grads
        self._grid_start, self._grid_tool, self._grid_end = grid_start, grid_tool, grid_end
        self._grid_start_adjoint = grid_start_adjoint
        self._seed, self._svd_adjoint, self._read_level = seed, svd_adjoint, read_level

    # ------------------------------------------------------------------ one env step
    def _grid(self, s: int, dt: float) -> list[int]:
        """Substep s's grid: scatter, gravity, the contact of each tool that can reach the touched box (in the
        simulator's order; the others leave every node of it as it is), floor and walls. Returns those tools."""
        self._box(s)
        t_now = (s + 1) * dt
        lo, hi = (b * self.engine.dx for b in np.split(self.bbox.to_numpy().astype(np.float64), 2))
        row = self._row
        centres = row[:, TS_POS:TS_POS + 3].astype(np.float64) + row[:, TS_VEL:TS_VEL + 3] * t_now
        gap = np.maximum(lo - centres, 0.0) + np.maximum(centres - hi, 0.0)  # centre to the box, per axis
        reach = (gap**2).sum(1) < self._bound2
        active = [t for t in range(self._n_tools) if reach[t]]
        self._clear_box()
        self._p2g(s)
        self._grid_start()
        for j, t in enumerate(active):
            self._grid_tool(t, j, t_now)
        self._grid_end(len(active))
        return active

    def forward_step(self, state: tuple, tool_row: np.ndarray, dt: float) -> tuple:
        """Run one env step from ``state`` = (x, v, F, C) with the tool rows (MAX_TOOLS, TS); fills the history
        and returns the end state (numpy float32)."""
        n = state[0].shape[0]
        self.n_p[None] = n
        self._load(*(np.ascontiguousarray(a, dtype=np.float32) for a in state))
        self._row = np.asarray(tool_row, dtype=np.float32)
        self.tool.from_numpy(self._row)
        statics = self.engine.statics
        self._n_tools = int(statics["n_tools"][None])
        self._bound2 = statics["tool_bound2"].to_numpy().astype(np.float64) * (1 + 1e-4)  # the kernel's skip radius
        for s in range(self.n_sub):
            self._trial_svd(s)
            self._stress(s)
            self._grid(s, dt)
            self._g2p(s)
            self._clear_box()
        return self._level(self.n_sub, n, grads=False)

    def backward_step(self, grads: tuple, dt: float) -> tuple[tuple, np.ndarray]:
        """After :meth:`forward_step`: from the gradients of the end state (x, v, F, C) to those of the start
        state, and of the tool rows (MAX_TOOLS, TS)."""
        n = int(self.n_p[None])
        S = self.n_sub
        self._clear_grads()
        self._seed(S, *(np.ascontiguousarray(g, dtype=np.float32) for g in grads))
        for s in reversed(range(S)):
            active = self._grid(s, dt)  # rebuild this substep's grid (and zero its gradients)
            self._g2p.grad(s)
            self._grid_end.grad(len(active))
            for j, t in reversed(list(enumerate(active))):
                self._grid_tool.grad(t, j, (s + 1) * dt)
            self._grid_start_adjoint()
            self._p2g.grad(s)
            self._stress.grad(s)
            self._svd_adjoint(s)
            self._clear_box()
        return self._level(0, n, grads=True), self.tool.grad.to_numpy()

    def _level(self, s: int, n: int, grads: bool) -> tuple:
        out = (np.zeros((n, 3), np.float32), np.zeros((n, 3), np.float32), np.zeros((n, 3, 3), np.float32),
               np.zeros((n, 3, 3), np.float32))
        self._read_level(s, *out, int(grads))
        return out


_GRAD_ENGINES: dict = {}


def grad_engine(sim: Simulator) -> GradEngine:
    """The differentiable driver for ``sim``'s engine layout and substeps (built, and compiled or loaded from
    the offline cache, on first use in a process)."""
    eng = sim._eng
    key = (id(eng), sim.cfg.substeps)
    if key not in _GRAD_ENGINES:
        _GRAD_ENGINES[key] = GradEngine(eng, sim.cfg.substeps)
    return _GRAD_ENGINES[key]


class _TorchOps:
    """:meth:`ToolTable.motion`'s array operations on float64 torch tensors (a scalar may be a plain float)."""

    @staticmethod
    def _t(v):
        return v if isinstance(v, torch.Tensor) else torch.tensor(float(v), dtype=torch.float64)

    @staticmethod
    def cos(v):
        return torch.cos(_TorchOps._t(v))

    @staticmethod
    def sin(v):
        return torch.sin(_TorchOps._t(v))

    @staticmethod
    def vec(values):
        return torch.stack([_TorchOps._t(v) for v in values])

    @staticmethod
    def clip(v, lo, hi):
        v = _TorchOps._t(v)
        return torch.clamp(v, torch.as_tensor(lo, dtype=v.dtype), torch.as_tensor(hi, dtype=v.dtype))

    @staticmethod
    def zeros3():
        return torch.zeros(3, dtype=torch.float64)

    @staticmethod
    def add_y(v, value):
        return v + torch.stack([torch.zeros((), dtype=v.dtype), _TorchOps._t(value), torch.zeros((), dtype=v.dtype)])


# ---------------------------------------------------------------------- tool kinematics in torch
def tool_rows(sim: Simulator, actions: Mapping[str, torch.Tensor], poses: Mapping[str, torch.Tensor] | None = None
              ) -> torch.Tensor:
    """The kernel's tool rows (T, MAX_TOOLS, TS) of a sequence of actions, differentiable with respect to the
    actions and the initial poses: :meth:`Simulator.step`'s kinematics (:meth:`ToolTable.motion`) on torch.

    ``actions``: {tool: (T, k) tensor}, k between the tool's required and all channels (clipped to [-1, 1]
    as ``step`` does); ``poses``: {tool: (6,) tensor (x, y, z, yaw, spin, aperture)} replacing the tool's
    current state (default: the simulator's). Tools not in ``actions`` stay where they are.
    """
    if not actions:
        raise InputError("rollout needs actions for at least one tool: {tool name: (T, channels) tensor}")
    poses = dict(poses or {})
    T = None
    for name, a in actions.items():
        sim._check_tool(name)
        spec = sim._table.spec(name)
        req = spec.required_action if spec.required_action is not None else spec.action_dim
        if not isinstance(a, torch.Tensor) or a.ndim != 2 or not req <= a.shape[1] <= spec.action_dim:
            raise InputError(f"actions['{name}'] must be a (T, k) tensor with k channels of {spec.channels}, got "
                             f"{getattr(a, 'shape', type(a).__name__)}")
        if T is not None and a.shape[0] != T:
            raise InputError(f"actions must all have the same length T; '{name}' has {a.shape[0]}, another {T}")
        T = a.shape[0]
        if not torch.isfinite(a).all():
            raise InputError(f"actions['{name}'] contains NaN or inf")
    for name, p in poses.items():
        sim._check_tool(name)
        if not isinstance(p, torch.Tensor) or p.shape != (6,):
            raise InputError(f"poses['{name}'] must be a (6,) tensor (x, y, z, yaw, spin, aperture), got "
                             f"{getattr(p, 'shape', type(p).__name__)}")
    assert T is not None
    dtype = torch.float64
    Tstep = sim.cfg.substeps * sim.params["dt"]
    cur = {name: (poses[name].to(dtype) if name in poses else torch.as_tensor(sim._tools[name], dtype=dtype))
           for name in sim.tool_names}
    zero = torch.zeros((), dtype=dtype)
    steps = []
    for k in range(T):
        rows = [[zero] * TS for _ in range(MAX_TOOLS)]
        for i, name in enumerate(sim.tool_names):
            c = cur[name]
            rows[i][TS_POS:TS_POS + 3] = [c[0], c[1], c[2]]
            rows[i][TS_YAW], rows[i][TS_AP] = c[3], c[5]
        for name, a in actions.items():
            spec = sim._table.spec(name)
            scales = torch.as_tensor(spec.action_scales[: a.shape[1]], dtype=dtype)
            vel, omega, yaw_rate, ap_rate, cur[name] = sim._table.motion(
                name, cur[name], torch.clamp(a[k].to(dtype), -1.0, 1.0) * scales, Tstep, _TorchOps)
            i = sim._table.index[name]
            rows[i][TS_VEL:TS_VEL + 3] = [vel[0], vel[1], vel[2]]
            rows[i][TS_OMEGA:TS_OMEGA + 3] = [omega[0], omega[1], omega[2]]
            rows[i][TS_YAWRATE] = yaw_rate + zero
            rows[i][TS_APRATE] = ap_rate + zero
        steps.append(torch.stack([torch.stack(r) for r in rows]))
    return torch.stack(steps)


# ---------------------------------------------------------------------- the autograd bridge
class _Rollout(torch.autograd.Function):
    """rows (T, MAX_TOOLS, TS) -> particle positions (T + 1, N, 3) at every env step boundary."""

    @staticmethod
    def forward(ctx, rows: torch.Tensor, sim: Simulator, start: tuple) -> torch.Tensor:
        ge = grad_engine(sim)
        sim._activate()  # the engine's parameter and tool fields hold this simulator's
        dt = sim.params["dt"]
        rows_np = rows.detach().cpu().numpy().astype(np.float32)
        states = [start]
        bad = sim._eng.bad
        for k in range(rows_np.shape[0]):
            sim._eng.reset_bad()
            states.append(ge.forward_step(states[-1], rows_np[k], dt))
            counts = bad.to_numpy()
            if counts.any():
                raise InputError(f"the rollout diverged in env step {k + 1} ({int(counts[0])} particle updates "
                                 f"non-finite or too fast, {int(counts[1])} left the unit cube): smaller actions")
        ctx.sim, ctx.states, ctx.rows = sim, states, rows_np
        ctx.out_dtype, ctx.device = rows.dtype, rows.device
        return torch.as_tensor(np.stack([s[0] for s in states]), dtype=torch.float32, device=rows.device)

    @staticmethod
    def backward(ctx, grad_x: torch.Tensor):
        sim, states, rows = ctx.sim, ctx.states, ctx.rows
        ge = grad_engine(sim)
        sim._activate()
        dt = sim.params["dt"]
        gx = grad_x.detach().cpu().numpy().astype(np.float32)
        n = states[0][0].shape[0]
        g = (gx[-1].copy(), np.zeros((n, 3), np.float32), np.zeros((n, 3, 3), np.float32),
             np.zeros((n, 3, 3), np.float32))
        g_rows = np.zeros(rows.shape, np.float64)
        for k in reversed(range(rows.shape[0])):
            ge.forward_step(states[k], rows[k], dt)
            g, g_rows[k] = ge.backward_step(g, dt)
            g = (g[0] + gx[k], *g[1:])
        return torch.as_tensor(g_rows, dtype=ctx.out_dtype, device=ctx.device), None, None


def rollout(sim: Simulator, actions: Mapping[str, torch.Tensor], poses: Mapping[str, torch.Tensor] | None = None,
            every_step: bool = False) -> torch.Tensor:
    """Simulate ``actions`` from ``sim``'s current state, differentiably; ``sim`` itself does not move.

    Args:
        sim: the simulator, holding the start state (its particles, tools and parameters).
        actions: {tool name: (T, k) tensor}, the tool's action channels per env step as
            :meth:`Simulator.step` takes them; every tool listed moves in every step.
        poses: {tool name: (6,) tensor (x, y, z, yaw, spin, aperture)}: start poses replacing the simulator's.
        every_step: return the positions at every env step boundary, (T + 1, N, 3), instead of the final
            ones, (N, 3).

    Returns the particle positions (float32); ``backward`` on a loss of them fills the gradients of the
    actions and poses that require them. Forward cost: one simulated step per step plus a copy of the start
    state per step; backward: one more forward and one adjoint per step. Raises InputError when the
    rollout diverges (the forward simulator would raise SimulationDiverged).
    """
    return rollout_rows(sim, tool_rows(sim, actions, poses), every_step=every_step)


def chain_rows(sim: Simulator, segments: Sequence[tuple[Mapping[str, torch.Tensor], Mapping[str, torch.Tensor] | None]]
               ) -> torch.Tensor:
    """The tool rows (T, MAX_TOOLS, TS) of a chain of tool moves, each ``(actions, poses)`` as
    :func:`tool_rows` takes them: segment after segment, each starting from its own ``poses`` (a tool
    teleported between segments, as an executed skill step places its tool and parks it afterwards; a tool
    a segment gives no pose starts it where ``sim`` has it now). Differentiable like :func:`tool_rows`."""
    if not segments:
        raise InputError("chain_rows needs at least one (actions, poses) segment")
    return torch.cat([tool_rows(sim, actions, poses) for actions, poses in segments])


def tool_positions(sim: Simulator, rows: torch.Tensor, name: str) -> torch.Tensor:
    """``(T, 3)``: the centre of tool ``name`` at the start of each env step of ``rows`` (:func:`tool_rows`)."""
    sim._check_tool(name)
    return rows[:, sim._table.index[name], TS_POS:TS_POS + 3]


def rollout_rows(sim: Simulator, rows: torch.Tensor, every_step: bool = False) -> torch.Tensor:
    """:func:`rollout` of given tool rows (:func:`tool_rows`, :func:`chain_rows`): the particle positions,
    final ``(N, 3)`` or at every env step boundary ``(T + 1, N, 3)``, differentiable with respect to ``rows``."""
    sim._need_scene()
    if not isinstance(rows, torch.Tensor) or rows.ndim != 3 or tuple(rows.shape[1:]) != (MAX_TOOLS, TS):
        raise InputError(f"rows must be a (T, {MAX_TOOLS}, {TS}) tensor (tool_rows), got "
                         f"{getattr(rows, 'shape', type(rows).__name__)}")
    st = sim.get_state()
    start = (st.x.astype(np.float32), st.v.astype(np.float32), st.F.astype(np.float32), st.C.astype(np.float32))
    xs = _Rollout.apply(rows, sim, start)
    return xs if every_step else xs[-1]


# ---------------------------------------------------------------------- losses
def chamfer(x: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Symmetric Chamfer distance (mean nearest-neighbour distance both ways) between (N, 3) and (M, 3)."""
    d = torch.cdist(x, target)
    return d.min(1).values.mean() + d.min(0).values.mean()


def _entropic_ot(x: torch.Tensor, y: torch.Tensor, eps: float, iters: int, p: int) -> torch.Tensor:
    """Entropic OT between uniform clouds with the cost |x - y|^p: its dual value, with the gradient of the
    converged problem (envelope theorem: the potentials are solved without a graph, the transport plan then
    weighs the cost's gradient), so the backward pass costs one cost matrix, not ``iters`` unrolled iterations."""
    diff = x[:, None, :] - y[None, :, :]
    sq = (diff ** 2).sum(-1)
    cost = sq if p == 2 else torch.sqrt(sq + 1e-12)  # the offset: a finite gradient where two points coincide
    n, m = cost.shape
    log_a = torch.full((n,), -math.log(n), dtype=cost.dtype, device=cost.device)
    log_b = torch.full((m,), -math.log(m), dtype=cost.dtype, device=cost.device)
    c = cost.detach()
    with torch.no_grad():
        f = torch.zeros(n, dtype=cost.dtype, device=cost.device)
        g = torch.zeros(m, dtype=cost.dtype, device=cost.device)
        for _ in range(iters):
            f = -eps * torch.logsumexp(log_b[None, :] + (g[None, :] - c) / eps, dim=1)
            g = -eps * torch.logsumexp(log_a[:, None] + (f[:, None] - c) / eps, dim=0)
        plan = torch.exp(log_a[:, None] + log_b[None, :] + (f[:, None] + g[None, :] - c) / eps)
        value = (log_a.exp() * f).sum() + (log_b.exp() * g).sum()
    weighted = (plan * cost).sum()
    return value + weighted - weighted.detach()


def sinkhorn(x: torch.Tensor, target: torch.Tensor, eps: float = 1e-4, iters: int = 200, p: int = 2) -> torch.Tensor:
    """The Sinkhorn divergence between two uniform clouds (N, 3), (M, 3) with the ground cost |x - y|^p (p = 1:
    the Euclidean distance, an EMD as the tasks score it; p = 2: its square): OT(x, target) - OT(x, x) / 2 -
    OT(target, target) / 2 with OT the entropic transport (log domain, ``iters`` iterations, blur ``eps`` in the
    cost's units, metres^p; smaller: closer to the exact transport, slower to converge). The
    debiasing terms make it zero when the clouds are equal: plain entropic OT is smallest for a cloud shrunk
    toward the target's centre (it sees every pair at a large blur), which an optimiser then finds. A pure
    translation by d costs |d|^p."""
    if eps <= 0 or iters < 1 or p not in (1, 2):
        raise InputError(f"sinkhorn needs eps > 0, iters >= 1 and p 1 or 2, got eps={eps}, iters={iters}, p={p}")
    return (_entropic_ot(x, target, eps, iters, p) - 0.5 * _entropic_ot(x, x, eps, iters, p)
            - 0.5 * _entropic_ot(target, target, eps, iters, p))


def gradient(sim: Simulator, actions: Mapping[str, np.ndarray | torch.Tensor], loss: Callable[[torch.Tensor], torch.Tensor],
             poses: Mapping[str, np.ndarray | torch.Tensor] | None = None, every_step: bool = False
             ) -> tuple[float, dict[str, np.ndarray], dict[str, np.ndarray]]:
    """The loss of a rollout and its gradients: ``(loss, {tool: d loss / d actions (T, k)}, {tool: d loss / d
    start pose (6,)})``. ``loss`` maps the positions (``(N, 3)``, or ``(T + 1, N, 3)`` with ``every_step``) to
    a scalar tensor, e.g. ``lambda x: chamfer(x, target)``. ``poses`` default to the simulator's tool states;
    the pose gradient is returned for every simulated tool."""
    acts = {k: torch.as_tensor(np.asarray(a, dtype=np.float64) if not isinstance(a, torch.Tensor) else a,
                               dtype=torch.float64).detach().clone().requires_grad_(True) for k, a in actions.items()}
    base = {name: sim._tools[name] for name in sim.tool_names}
    if poses:
        base.update({k: np.asarray(p.detach().numpy() if isinstance(p, torch.Tensor) else p) for k, p in poses.items()})
    pose_t = {k: torch.as_tensor(np.asarray(p, dtype=np.float64)).requires_grad_(True) for k, p in base.items()}
    value = loss(rollout(sim, acts, pose_t, every_step=every_step))
    if not isinstance(value, torch.Tensor) or value.numel() != 1:
        raise InputError(f"loss must return a scalar tensor, got {getattr(value, 'shape', type(value).__name__)}")
    value.backward()
    return (float(value.detach()), {k: (a.grad.numpy() if a.grad is not None else np.zeros(a.shape)) for k, a in acts.items()},
            {k: (p.grad.numpy() if p.grad is not None else np.zeros(6)) for k, p in pose_t.items()})
