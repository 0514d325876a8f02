"""The Taichi side: runtime initialisation, fields and MLS-MPM kernels.

:func:`physics` holds the physics once, as Taichi functions over whichever fields a driver passes: the
constitutive model (von Mises return mapping on log singular values, fixed-corotated stress, the APIC
"affine" matrix), the quadratic B-spline scatter and gather, the grid-node update (momentum -> velocity,
gravity, tool contact in a soft SDF band with Coulomb friction, floor friction with a second friction inside
the spreading area, free-slip walls) and the advection with its divergence check. Two drivers use it:

- :class:`Engine`, the forward simulator: one kernel launch per substep and one parallel loop in it (the
  constitutive update with a warm-started one-sweep SVD, :func:`svd_sweep` on 4 particles at once in SSE
  registers, runs in the previous substep's particle loop; the
  scatter as one serialized loop on CPU, where Taichi demotes the atomics to plain adds: about 3x faster
  than the parallel atomic scatter and bitwise deterministic; clearing and updating the touched box of the
  grid serially, cheaper than a thread-pool dispatch; the gather and advection in parallel).
- :class:`pasta.sim.grad.GradEngine`, the differentiable one: per-substep particle history, Taichi
  autodiff kernels and a hand-written SVD adjoint (docs/simulator.md, "Gradients").

Tools are runtime data too: up to ``MAX_TOOLS`` tools of up to ``MAX_PRIMS`` primitives each, their
kinds, sizes, offsets, bounding radii and frictions in fields (``pasta.sim.tools.ToolTable`` fills
them). The kernels name no tool, so a new tool set reuses the compiled (or offline-cached) kernels.
Tools are applied to a grid node one after the other in the simulator's tool order.
"""


import os
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import taichi as ti

from pasta.core.errors import ConfigError

from .tools import GEO, KIND_IDS, MAX_PRIMS, MAX_TOOLS

# ---- runtime parameter slots (one f32 field) -------------------------------------------------
P_DT, P_MU, P_LAM, P_YIELD, P_GRAVITY, P_GROUND_FRIC, P_SPREAD_FRIC, P_SPREAD_X0, P_SPREAD_X1, P_SOFTNESS = range(10)
N_PARAMS = 10

# ---- tool state slots (one (MAX_TOOLS, TS) f32 field, written once per env step) ---------------
# position at the start of the env step (3), yaw at the start (1), linear velocity (3),
# angular velocity (3, world frame, includes a rolling tool's spin), yaw rate (1),
# finger-pair aperture at the start (1), aperture rate (1)
TS_POS, TS_YAW, TS_VEL, TS_OMEGA, TS_YAWRATE, TS_AP, TS_APRATE = 0, 3, 4, 7, 10, 11, 12
TS = 13

K_BOX, K_WEDGE, K_CAPSULE, K_FINGERS = (KIND_IDS[k] for k in ("box", "wedge_blade", "capsule", "finger_pair"))

WALL_CELLS = 3  # free-slip band at the side walls and the ceiling
FLOOR_CELLS = 2  # floor band (nodes j < FLOOR_CELLS get the floor condition)
P_VOL_FACTOR = 0.125  # particle volume = (dx / 2)^3; the dynamics depend only on E / rho
RHO = 1.0
LANES = 4  # particles whose SVDs run side by side in SSE registers (svd_sweep)

_TI_STATE: dict = {}

#: Taichi ``fast_math`` when the caller does not say (``SimConfig.fast_math`` does). Off: LLVM then keeps
#: IEEE semantics (no FMA contraction or reassociation chosen per host CPU, no "no NaN" assumption that
#: could fold away the divergence check), so the same seed gives the same task instance on other x86-64
#: machines; it costs about 23% simulator time (docs/simulator.md, "Reproducibility").
FAST_MATH = False


def cache_dir() -> str:
    """Offline-cache folder for compiled kernels: $PASTA_TAICHI_CACHE or ~/.cache/pasta/taichi."""
    return os.environ.get("PASTA_TAICHI_CACHE") or str(Path.home() / ".cache" / "pasta" / "taichi")


def ensure_taichi(arch: str = "cpu", cpu_threads: int = 2, fast_math: bool | None = None) -> None:
    """Initialise Taichi once per process; later calls with the same settings reuse the runtime.

    ``fast_math``: let LLVM reassociate and contract floating-point operations. It is a compile option of
    the whole runtime, so one process has one value; ``None``: the running runtime's value, or
    :data:`FAST_MATH` when Taichi is not running yet. See docs/simulator.md, "Reproducibility".
    """
    if fast_math is None:
        fast_math = _TI_STATE["fast_math"] if _TI_STATE else FAST_MATH
    if _TI_STATE:
        if _TI_STATE["arch"] != arch:
            raise ConfigError(
                f"sim.arch={arch!r}: Taichi is already running with arch={_TI_STATE['arch']!r} in this "
                "process; one Taichi runtime per process (use the same arch for every Simulator)"
            )
        if _TI_STATE["fast_math"] != bool(fast_math):
            raise ConfigError(
                f"sim.fast_math={bool(fast_math)}: Taichi is already running with fast_math={_TI_STATE['fast_math']} "
                "in this process; one Taichi runtime per process (use the same value for every Simulator)"
            )
        return
    archs = {"cpu": ti.cpu, "cuda": ti.cuda, "gpu": ti.gpu, "vulkan": ti.vulkan, "metal": ti.metal}
    kwargs = {
        "arch": archs[arch],
        "default_fp": ti.f32,
        "default_ip": ti.i32,
        "fast_math": bool(fast_math),
        "offline_cache": True,
        "offline_cache_file_path": cache_dir(),
        "random_seed": 0,
        "log_level": ti.WARN,
    }
    if arch == "cpu" and cpu_threads > 0:
        kwargs["cpu_max_num_threads"] = cpu_threads
    os.makedirs(cache_dir(), exist_ok=True)
    ti.init(**kwargs)
    _TI_STATE.update(arch=arch, fast_math=bool(fast_math))


def taichi_settings() -> dict:
    """The running Taichi runtime's arch and compile options (``{}`` before :func:`ensure_taichi`)."""
    if not _TI_STATE:
        return {}
    cfg = ti.lang.impl.current_cfg()
    return {"arch": _TI_STATE["arch"], "backend": str(cfg.arch).rpartition(".")[2], "fast_math": bool(cfg.fast_math),
            "cpu_max_num_threads": int(cfg.cpu_max_num_threads), "default_fp": str(cfg.default_fp),
            "opt_level": int(cfg.opt_level), "advanced_optimization": bool(cfg.advanced_optimization),
            "debug": bool(cfg.debug), "random_seed": int(cfg.random_seed)}


@ti.func
def svd_sweep(Fp, V, lanes: ti.template()):  # type: ignore[valid-type]  # Taichi's idiom
    """The warm-started SVD (``physics(...).warm_svd``) of ``lanes`` particles side by side. ``Fp``, ``V``: (9, lanes)
    matrices, column k holding particle k's 3x3 matrix row-major. Branch-free (selects), so that with 4 lanes LLVM
    emits SSE square roots and divisions for 4 particles at once (1.6x faster than one at a time on one thread, 5k
    particles); each lane computes the same operations in the same order as one particle alone, so the floats are
    the same bits whatever ``lanes`` is. Returns U (9, lanes), sig (3, lanes), V (9, lanes).

    One cyclic Jacobi sweep (3 exact rotations) on V^T (Fp^T Fp) V, then Gram-Schmidt on Fp V. Each rotation J is
    the identity but for J[p, p] = J[q, q] = c, J[p, q] = sn, J[q, p] = -sn, so only rows and columns p and q
    change (without fast_math LLVM keeps products with zeros, so they are not written as 3x3 products)."""
    F3 = [[ti.Vector([Fp[3 * i + j, k] for k in ti.static(range(lanes))]) for j in ti.static(range(3))]
          for i in ti.static(range(3))]
    V3 = [[ti.Vector([V[3 * i + j, k] for k in ti.static(range(lanes))]) for j in ti.static(range(3))]
          for i in ti.static(range(3))]
    G = [[F3[0][i] * F3[0][j] + F3[1][i] * F3[1][j] + F3[2][i] * F3[2][j] for j in ti.static(range(3))]
         for i in ti.static(range(3))]  # Fp^T Fp
    T = [[V3[0][i] * G[0][j] + V3[1][i] * G[1][j] + V3[2][i] * G[2][j] for j in ti.static(range(3))]
         for i in ti.static(range(3))]  # V^T (Fp^T Fp)
    S = [[T[i][0] * V3[0][j] + T[i][1] * V3[1][j] + T[i][2] * V3[2][j] for j in ti.static(range(3))]
         for i in ti.static(range(3))]
    for p, q in ti.static(((0, 1), (0, 2), (1, 2))):
        spq = S[p][q]
        d = 0.5 * (S[q][q] - S[p][p])
        root = ti.sqrt(d * d + spq * spq)
        den = ti.select(d >= 0, d + root, d - root)
        t = ti.select(ti.abs(den) > 1e-30, spq / den, 0.0)
        c = 1.0 / ti.sqrt(1.0 + t * t)
        sn = t * c
        JS = [[S[i][j] for j in ti.static(range(3))] for i in ti.static(range(3))]
        for j in ti.static(range(3)):  # rows p and q of J^T S
            JS[p][j] = c * S[p][j] - sn * S[q][j]
            JS[q][j] = sn * S[p][j] + c * S[q][j]
        VJ = [[V3[i][j] for j in ti.static(range(3))] for i in ti.static(range(3))]
        for i in ti.static(range(3)):  # columns p and q of (J^T S) J and of V J
            VJ[i][p] = c * V3[i][p] - sn * V3[i][q]
            VJ[i][q] = sn * V3[i][p] + c * V3[i][q]
        for i, j in ti.static(ti.ndrange(3, 3)):
            S[i][j] = JS[i][j]
            V3[i][j] = VJ[i][j]
        for i in ti.static(range(3)):
            S[i][p] = c * JS[i][p] - sn * JS[i][q]
            S[i][q] = sn * JS[i][p] + c * JS[i][q]
    B = [[F3[i][0] * V3[0][j] + F3[i][1] * V3[1][j] + F3[i][2] * V3[2][j] for j in ti.static(range(3))]
         for i in ti.static(range(3))]  # Fp V
    b0 = [B[i][0] for i in ti.static(range(3))]
    b1 = [B[i][1] for i in ti.static(range(3))]
    b2 = [B[i][2] for i in ti.static(range(3))]
    s0 = ti.max(ti.sqrt(b0[0] * b0[0] + b0[1] * b0[1] + b0[2] * b0[2]), 1e-12)
    u0 = [b0[i] / s0 for i in ti.static(range(3))]
    g = u0[0] * b1[0] + u0[1] * b1[1] + u0[2] * b1[2]
    c1 = [b1[i] - g * u0[i] for i in ti.static(range(3))]
    s1 = ti.max(ti.sqrt(c1[0] * c1[0] + c1[1] * c1[1] + c1[2] * c1[2]), 1e-12)
    u1 = [c1[i] / s1 for i in ti.static(range(3))]
    u2 = [u0[1] * u1[2] - u0[2] * u1[1], u0[2] * u1[0] - u0[0] * u1[2], u0[0] * u1[1] - u0[1] * u1[0]]
    s2 = u2[0] * b2[0] + u2[1] * b2[1] + u2[2] * b2[2]
    U9 = ti.Matrix([[[u0, u1, u2][j][i][k] for k in ti.static(range(lanes))] for i, j in ti.static(ti.ndrange(3, 3))])
    V9 = ti.Matrix([[V3[i][j][k] for k in ti.static(range(lanes))] for i, j in ti.static(ti.ndrange(3, 3))])
    sig = ti.Matrix([[[s0, s1, s2][i][k] for k in ti.static(range(lanes))] for i in ti.static(range(3))])
    return U9, sig, V9


def physics(n: int, params, tool, statics: dict, differentiable: bool = False):
    """The MLS-MPM physics as Taichi functions over the given fields, shared by the forward :class:`Engine`
    and the differentiable :class:`~pasta.sim.grad.GradEngine` (one copy of the physics, two drivers).

    ``params``: the runtime parameter field (``P_*`` slots); ``tool``: the (MAX_TOOLS, TS) tool-state field
    of the env step; ``statics``: the static tool fields by name (``n_tools``, ``tool_kind``, ``tool_geo``,
    ``tool_n_prims``, ``tool_bound2``, ``tool_fric``). Returns a namespace of ``ti.func`` s:
    ``node_velocity(I, mv, t_now)`` (and its three parts ``node_start``, ``node_contact``, ``node_bounds``),
    ``warm_svd(Fp, V)``, ``return_map(sig)``, ``compose(U, s, V)``, ``affine(Fp, U, V, s, Cp)``,
    ``scatter(grid, xp, vp, Ap)``, ``gather(grid, xp)``, ``advance(xp, new_v, new_C, bad)``, and the touched-box
    helpers ``box_extent(bbox)``, ``box_store(bbox, lo, hi)``, ``box_include(bbox, base)``,
    ``box_node(lo, ext, tt)``.
    ``differentiable``: the variant for reverse-mode autodiff, the same physics: the loop over a tool's
    primitives unrolled (Taichi's autodiff cannot take a loop whose bound is read inside another loop) and
    every vector length through :func:`length`, whose gradient at zero is zero, not NaN (the friction of a
    node at rest relative to a tool or the floor).
    """
    dx = 1.0 / n
    inv_dx = float(n)
    p_vol = P_VOL_FACTOR * dx**3
    p_mass = p_vol * RHO
    lo_clamp = ti.Vector([2 * dx, dx, 2 * dx])
    hi_clamp = ti.Vector([1 - 3 * dx, 1 - 3 * dx, 1 - 3 * dx])
    n_tools, tool_kind, tool_geo = statics["n_tools"], statics["tool_kind"], statics["tool_geo"]

    @ti.func
    def length(v):
        """|v|; in the differentiable variant sqrt(v.v + 1e-30), whose gradient at v = 0 is 0 (the forward
        value differs below 1e-15)."""
        out = 0.0
        if ti.static(differentiable):
            out = ti.sqrt(v.dot(v) + 1e-30)
        else:
            out = v.norm()
        return out
    tool_n_prims, tool_bound2, tool_fric = statics["tool_n_prims"], statics["tool_bound2"], statics["tool_fric"]

    @ti.func
    def box_sdf(q, h):
        d = ti.abs(q) - h
        sgn = ti.Vector([1.0 if q[0] >= 0 else -1.0, 1.0 if q[1] >= 0 else -1.0, 1.0 if q[2] >= 0 else -1.0])
        dist = 0.0
        nrm = ti.Vector([0.0, 0.0, 0.0])
        dmax = ti.max(d[0], d[1], d[2])
        if dmax > 0:
            o = ti.max(d, 0.0)
            dist = length(o)
            nrm = o / ti.max(dist, 1e-12) * sgn
        else:
            dist = dmax
            if d[0] >= d[1] and d[0] >= d[2]:
                nrm[0] = sgn[0]
            elif d[1] >= d[2]:
                nrm[1] = sgn[1]
            else:
                nrm[2] = sgn[2]
        return dist, nrm

    @ti.func
    def prim_sdf(t, k, q, ap):
        """Signed distance, outward unit normal (tool frame) and finger side (-1, 0, +1: which finger of
        a finger pair is nearest, whose opening velocity the contact sees) of primitive k of tool t."""
        kind = tool_kind[t, k]
        qp = q - ti.Vector([tool_geo[t, k, 0], tool_geo[t, k, 1], tool_geo[t, k, 2]])
        h = ti.Vector([tool_geo[t, k, 3], tool_geo[t, k, 4], tool_geo[t, k, 5]])
        dist = 0.0
        nrm = ti.Vector([0.0, 1.0, 0.0])
        side = 0.0
        if kind == K_CAPSULE:  # along local z: h = (radius, half length, -)
            cz = ti.min(ti.max(qp[2], -h[1]), h[1])
            r = qp - ti.Vector([0.0, 0.0, cz])
            ln = length(r)
            dist = ln - h[0]
            if ln > 1e-9:
                nrm = r / ln
        elif kind == K_FINGERS:  # two boxes h at local x = +-(aperture / 2 + h[0])
            side = 1.0 if qp[0] >= 0 else -1.0
            dist, nrm = box_sdf(qp - ti.Vector([side * (ap * 0.5 + h[0]), 0.0, 0.0]), h)
        else:
            dist, nrm = box_sdf(qp, h)
            if kind == K_WEDGE:  # box intersected with a downward wedge whose edge is the box bottom
                ca = tool_geo[t, k, 6]
                sa = tool_geo[t, k, 7]
                r = qp - ti.Vector([0.0, -h[1], 0.0])
                p1 = r[0] * ca - r[1] * sa
                p2 = -r[0] * ca - r[1] * sa
                if p1 > dist and p1 >= p2:
                    dist = p1
                    nrm = ti.Vector([ca, -sa, 0.0])
                elif p2 > dist:
                    dist = p2
                    nrm = ti.Vector([-ca, -sa, 0.0])
        return dist, nrm, side

    @ti.func
    def tool_sdf(t, q, ap):
        """Union of tool t's primitives: the nearest one's distance, normal and finger side."""
        dist = 0.0
        nrm = ti.Vector([0.0, 1.0, 0.0])
        side = 0.0
        if ti.static(differentiable):
            for k in ti.static(range(MAX_PRIMS)):
                if k < tool_n_prims[t]:
                    dk, nk, sk = prim_sdf(t, k, q, ap)
                    if k == 0 or dk < dist:
                        dist = dk
                        nrm = nk
                        side = sk
        else:
            for k in range(tool_n_prims[t]):
                dk, nk, sk = prim_sdf(t, k, q, ap)
                if k == 0 or dk < dist:
                    dist = dk
                    nrm = nk
                    side = sk
        return dist, nrm, side

    @ti.func
    def tool_contact(t, xn, vel, t_now, soft, band):
        """Grid velocity ``vel`` at node position ``xn`` after tool t's contact (soft SDF band, Coulomb
        friction): unchanged outside the band."""
        out = vel
        tv = ti.Vector([tool[t, TS_VEL], tool[t, TS_VEL + 1], tool[t, TS_VEL + 2]])
        c = ti.Vector([tool[t, TS_POS], tool[t, TS_POS + 1], tool[t, TS_POS + 2]]) + tv * t_now
        r = xn - c
        if r.norm_sqr() < tool_bound2[t]:
            yaw = tool[t, TS_YAW] + tool[t, TS_YAWRATE] * t_now
            cy, sy = ti.cos(yaw), ti.sin(yaw)
            q = ti.Vector([cy * r[0] - sy * r[2], r[1], sy * r[0] + cy * r[2]])
            ap = tool[t, TS_AP] + tool[t, TS_APRATE] * t_now
            d, nl, side = tool_sdf(t, q, ap)
            if d <= 0 or d < band:
                infl = ti.min(ti.exp(-d * soft), 1.0)
                nw = ti.Vector([cy * nl[0] + sy * nl[2], nl[1], -sy * nl[0] + cy * nl[2]])
                om = ti.Vector([tool[t, TS_OMEGA], tool[t, TS_OMEGA + 1], tool[t, TS_OMEGA + 2]])
                vt = tv + om.cross(r)
                if side != 0.0:  # a finger moves at half the aperture rate along local +-x
                    vt += (side * 0.5 * tool[t, TS_APRATE]) * ti.Vector([cy, 0.0, -sy])
                rel = out - vt
                vn = rel.dot(nw)
                tang = rel
                if vn < 0:
                    tang = rel - vn * nw
                    tl = length(tang)
                    tang = tang * (ti.max(0.0, tl + tool_fric[t] * vn) / ti.max(tl, 1e-12))
                out = vt + (1.0 - infl) * rel + infl * tang
        return out

    @ti.func
    def node_start(mv):
        """A grid node's velocity from its momentum ``mv`` = (m v, m), m > 0, plus one substep of gravity."""
        dt = params[P_DT]
        vel = ti.Vector([mv[0], mv[1], mv[2]]) / mv[3]
        vel[1] += dt * params[P_GRAVITY]
        return vel

    @ti.func
    def node_contact(t, I, vel, t_now):
        """Node I's velocity after tool t's contact (soft SDF band, Coulomb friction)."""
        soft = params[P_SOFTNESS]
        band = 0.0
        if soft > 0:
            band = 2.302585 / soft  # influence exp(-soft d) > 0.1
        return tool_contact(t, ti.cast(I, ti.f32) * dx, vel, t_now, soft, band)

    @ti.func
    def node_bounds(I, vel):
        """Node I's velocity after the floor (Coulomb friction, higher inside the spreading area) and the
        free-slip side walls and ceiling."""
        out = vel
        xn = ti.cast(I, ti.f32) * dx
        if I[1] < FLOOR_CELLS and out[1] < 0:
            mu_f = params[P_GROUND_FRIC]
            if params[P_SPREAD_X0] <= xn[0] and xn[0] <= params[P_SPREAD_X1]:
                mu_f = params[P_SPREAD_FRIC]
            tl = 0.0
            if ti.static(differentiable):
                tl = length(ti.Vector([out[0], out[2]]))
            else:
                tl = ti.sqrt(out[0] ** 2 + out[2] ** 2)
            scale = ti.max(0.0, tl + mu_f * out[1]) / ti.max(tl, 1e-12)
            out = ti.Vector([out[0] * scale, 0.0, out[2] * scale])
        for d in ti.static(range(3)):
            if ti.static(d != 1):  # noqa: SIM102 - a compile-time branch: no runtime `and` with it
                if I[d] < WALL_CELLS and out[d] < 0:
                    out[d] = 0.0
            if I[d] > n - WALL_CELLS and out[d] > 0:
                out[d] = 0.0
        return out

    @ti.func
    def node_velocity(I, mv, t_now):
        """Grid node I's new velocity from its momentum ``mv`` = (m v, m), m > 0: gravity, every tool's
        contact in the simulator's tool order, floor, walls."""
        vel = node_start(mv)
        for t in range(n_tools[None]):
            vel = node_contact(t, I, vel, t_now)
        return node_bounds(I, vel)

    @ti.func
    def warm_svd(Fp, V):
        """SVD of Fp warm-started from the previous right singular vectors V (a rotation): one
        cyclic Jacobi sweep on V^T Fp^T Fp V, then Gram-Schmidt on Fp V. F changes by
        (I + dt C) per substep, so V is already nearly right and one sweep suffices; V is
        recomputed by a full SVD at the start of every env step. Returns U, sig, V with U and V
        rotations (sig[2] < 0 for an inverted element), unsorted. (:func:`svd_sweep` on one lane.)"""
        U9, sig3, V9 = svd_sweep(ti.Matrix([[Fp[i, j]] for i, j in ti.static(ti.ndrange(3, 3))]),
                                 ti.Matrix([[V[i, j]] for i, j in ti.static(ti.ndrange(3, 3))]), 1)
        U = ti.Matrix([[U9[3 * i + j, 0] for j in ti.static(range(3))] for i in ti.static(range(3))])
        Vn = ti.Matrix([[V9[3 * i + j, 0] for j in ti.static(range(3))] for i in ti.static(range(3))])
        return U, ti.Vector([sig3[0, 0], sig3[1, 0], sig3[2, 0]]), Vn

    @ti.func
    def return_map(sig):
        """Von Mises return mapping on the log singular values: the new singular values, and whether they
        differ from ``sig`` (plastic flow, or an element squeezed below 5 %)."""
        yield_strain = params[P_YIELD] / (2.0 * params[P_MU])
        e = ti.log(ti.max(sig, 0.05))
        changed = sig.min() < 0.05
        e_hat = e - e.sum() / 3.0
        e_norm = ti.sqrt(e_hat.dot(e_hat) + 1e-12)
        dgamma = e_norm - yield_strain
        if dgamma > 0:
            e = e - dgamma / e_norm * e_hat
            changed = True
        return ti.exp(e), changed

    @ti.func
    def compose(U, s, V):
        """U diag(s) V^T (the diagonal as a column scaling: no products with zeros)."""
        Us = ti.Matrix.cols([ti.Vector([U[0, i], U[1, i], U[2, i]]) * s[i] for i in ti.static(range(3))])
        return Us @ V.transpose()

    @ti.func
    def affine(Fp, U, V, s, Cp):
        """Fixed-corotated stress of the deformation Fp = U diag(s) V^T, as the APIC affine momentum matrix
        the scatter spreads (stress term plus the particle's mass times its velocity gradient Cp)."""
        mu = params[P_MU]
        lam = params[P_LAM]
        J = s[0] * s[1] * s[2]
        R = U @ V.transpose()
        stress = 2.0 * mu * (Fp - R) @ Fp.transpose()
        pressure = lam * J * (J - 1.0)
        for i in ti.static(range(3)):  # + pressure I, without products with the identity's zeros
            stress[i, i] += pressure
        return (-params[P_DT] * p_vol * 4.0 * inv_dx * inv_dx) * stress + p_mass * Cp

    @ti.func
    def scatter(grid: ti.template(), xp, vp, Ap):  # type: ignore[valid-type]  # Taichi's idiom
        """P2G of one particle into ``grid`` (m v, m) (quadratic B-spline, APIC); returns its stencil base."""
        Xp = xp * inv_dx
        base = ti.cast(Xp - 0.5, ti.i32)
        fx = Xp - ti.cast(base, ti.f32)
        w = [0.5 * (1.5 - fx) ** 2, 0.75 - (fx - 1.0) ** 2, 0.5 * (fx - 0.5) ** 2]
        mv = p_mass * vp
        for i, j, k in ti.static(ti.ndrange(3, 3, 3)):
            dpos = (ti.Vector([i, j, k], ti.f32) - fx) * dx
            weight = w[i][0] * w[j][1] * w[k][2]
            mom = weight * (mv + Ap @ dpos)
            grid[base + ti.Vector([i, j, k])] += ti.Vector([mom[0], mom[1], mom[2], weight * p_mass])
        return base

    @ti.func
    def gather(grid: ti.template(), xp):  # type: ignore[valid-type]  # Taichi's idiom
        """G2P of one particle from ``grid`` (v, m): its new velocity and APIC C."""
        Xp = xp * inv_dx
        base = ti.cast(Xp - 0.5, ti.i32)
        fx = Xp - ti.cast(base, ti.f32)
        w = [0.5 * (1.5 - fx) ** 2, 0.75 - (fx - 1.0) ** 2, 0.5 * (fx - 0.5) ** 2]
        new_v = ti.Vector.zero(ti.f32, 3)
        new_C = ti.Matrix.zero(ti.f32, 3, 3)
        for i, j, k in ti.static(ti.ndrange(3, 3, 3)):
            dpos = ti.Vector([i, j, k], ti.f32) - fx
            gv = grid[base + ti.Vector([i, j, k])]
            gvel = ti.Vector([gv[0], gv[1], gv[2]])
            weight = w[i][0] * w[j][1] * w[k][2]
            new_v += weight * gvel
            new_C += (4.0 * inv_dx * weight) * gvel.outer_product(dpos)
        return new_v, new_C

    @ti.func
    def advance(xp, new_v, new_C, bad: ti.template()):  # type: ignore[valid-type]  # Taichi's idiom
        """Advect one particle; flag divergence in ``bad`` (non-finite or faster than dx/dt: the particle
        keeps its position, at rest; outside the unit cube) and clamp inside the walls. Returns x, v, C."""
        dt = params[P_DT]
        x_out = xp
        v_out = ti.Vector.zero(ti.f32, 3)
        C_out = ti.Matrix.zero(ti.f32, 3, 3)
        xn = xp + dt * new_v
        if not (new_v.norm_sqr() * dt * dt <= dx * dx):  # also catches NaN / inf
            ti.atomic_add(bad[0], 1)
        else:
            if xn.min() < 0.0 or xn.max() > 1.0:
                ti.atomic_add(bad[1], 1)
            v_out = new_v
            C_out = new_C
            x_out = ti.min(ti.max(xn, lo_clamp), hi_clamp)
        return x_out, v_out, C_out

    @ti.func
    def box_extent(bbox: ti.template()):  # type: ignore[valid-type]  # Taichi's idiom
        """The lowest node and the size of the box of grid nodes ``bbox`` (lo xyz, hi xyz inclusive) holds."""
        lo = ti.Vector([bbox[0], bbox[1], bbox[2]])
        ext = ti.max(ti.Vector([bbox[3], bbox[4], bbox[5]]) - lo + 1, 0)
        return lo, ext

    @ti.func
    def box_store(bbox: ti.template(), lo, hi):  # type: ignore[valid-type]  # Taichi's idiom
        """Write the box (lo, hi inclusive) of touched grid nodes; (n, -1) per axis: empty, for box_include."""
        for d in ti.static(range(3)):
            bbox[d] = lo[d]
            bbox[3 + d] = hi[d]

    @ti.func
    def box_include(bbox: ti.template(), base):  # type: ignore[valid-type]  # Taichi's idiom
        """Grow the box by a particle's 3x3x3 stencil at ``base`` (atomics: for a parallel loop)."""
        for d in ti.static(range(3)):
            ti.atomic_min(bbox[d], base[d])
            ti.atomic_max(bbox[3 + d], base[d] + 2)

    @ti.func
    def box_node(lo, ext, tt):
        """Node number ``tt`` of the box (lo, ext)."""
        return ti.Vector([lo[0] + tt // (ext[1] * ext[2]), lo[1] + (tt // ext[2]) % ext[1], lo[2] + tt % ext[2]])

    return SimpleNamespace(warm_svd=warm_svd, compose=compose, node_velocity=node_velocity, node_start=node_start, node_contact=node_contact,
                           node_bounds=node_bounds, return_map=return_map, affine=affine, scatter=scatter,
                           gather=gather, advance=advance, box_extent=box_extent, box_store=box_store,
                           box_include=box_include, box_node=box_node)


class Engine:
    """Fields and forward kernels for one (n_grid, max_particles) layout. Built once per process per layout.

    ``scatter``: "serial" (CPU default: deterministic, fastest on CPU) or "atomic" (GPU: parallel
    float atomics, not bitwise reproducible). One substep is one kernel launch; the SVD is a warm-started
    one-sweep Jacobi (``warm_svd``: 2.2x cheaper than Taichi's 5-sweep ``ti.svd``).
    """

    def __init__(self, n_grid: int, max_particles: int, scatter: str = "serial") -> None:
        if scatter not in ("serial", "atomic"):
            raise ConfigError(f"sim.scatter={scatter!r}: must be 'serial' or 'atomic'")
        self.n_grid = n = n_grid
        self.max_particles = max_particles
        self.dx = 1.0 / n
        self.p_vol = P_VOL_FACTOR * self.dx**3
        self.p_mass = self.p_vol * RHO
        self.scatter_mode = scatter

        # particles
        self.x = ti.Vector.field(3, ti.f32, shape=max_particles)
        self.v = ti.Vector.field(3, ti.f32, shape=max_particles)
        self.C = ti.Matrix.field(3, 3, ti.f32, shape=max_particles)
        self.F = ti.Matrix.field(3, 3, ti.f32, shape=max_particles)
        self.A = ti.Matrix.field(3, 3, ti.f32, shape=max_particles)  # scratch: APIC affine momentum
        self.Vr = ti.Matrix.field(3, 3, ti.f32, shape=max_particles)  # scratch: warm-start SVD rotation
        self.n_p = ti.field(ti.i32, shape=())
        # grid: (m v, m) per node, then (v, m) after the grid operation
        self.grid = ti.Vector.field(4, ti.f32, shape=(n, n, n))
        self.bbox = ti.field(ti.i32, shape=6)  # lo xyz, hi xyz of touched nodes (inclusive)
        self.bad = ti.field(ti.i32, shape=2)  # [non-finite or faster than dx/dt, left the unit cube]
        self.params = ti.field(ti.f32, shape=N_PARAMS)
        self.tool = ti.field(ti.f32, shape=(MAX_TOOLS, TS))
        # static tool data (ToolTable.kernel_arrays), rewritten when another tool set takes the engine
        self.statics = {
            "n_tools": ti.field(ti.i32, shape=()),
            "tool_kind": ti.field(ti.i32, shape=(MAX_TOOLS, MAX_PRIMS)),
            "tool_geo": ti.field(ti.f32, shape=(MAX_TOOLS, MAX_PRIMS, GEO)),
            "tool_n_prims": ti.field(ti.i32, shape=MAX_TOOLS),
            "tool_bound2": ti.field(ti.f32, shape=MAX_TOOLS),
            "tool_fric": ti.field(ti.f32, shape=MAX_TOOLS),
        }
        self.n_tools = self.statics["n_tools"]

        x, v, C, F, A, Vr, n_p, grid, bbox, bad, params = (
            self.x, self.v, self.C, self.F, self.A, self.Vr, self.n_p, self.grid, self.bbox, self.bad, self.params,
        )
        phys = physics(n, params, self.tool, self.statics)
        serial = scatter == "serial"

        @ti.func
        def constitutive_group(p0):
            """The constitutive update of particles p0 .. p0 + LANES - 1 (those below n_p): trial F, the
            warm-started SVD on LANES lanes at once (:func:`svd_sweep`), return mapping, fixed-corotated stress;
            writes F, Vr and the APIC affine matrix A. Bitwise what one particle at a time gives."""
            last_p = n_p[None] - 1
            Fs = [(ti.Matrix.identity(ti.f32, 3) + params[P_DT] * C[ti.min(p0 + k, last_p)]) @ F[ti.min(p0 + k, last_p)]
                  for k in ti.static(range(LANES))]
            Vs = [Vr[ti.min(p0 + k, last_p)] for k in ti.static(range(LANES))]
            U9, sig3, V9 = svd_sweep(
                ti.Matrix([[Fs[k][i, j] for k in ti.static(range(LANES))] for i, j in ti.static(ti.ndrange(3, 3))]),
                ti.Matrix([[Vs[k][i, j] for k in ti.static(range(LANES))] for i, j in ti.static(ti.ndrange(3, 3))]),
                LANES)
            for k in ti.static(range(LANES)):
                p = p0 + k
                if p <= last_p:
                    U = ti.Matrix([[U9[3 * i + j, k] for j in ti.static(range(3))] for i in ti.static(range(3))])
                    V = ti.Matrix([[V9[3 * i + j, k] for j in ti.static(range(3))] for i in ti.static(range(3))])
                    Vr[p] = V
                    s, _changed = phys.return_map(ti.Vector([sig3[i, k] for i in ti.static(range(3))]))
                    # with the approximate SVD always rebuild F so that F = U diag(s) V^T exactly
                    Fp = phys.compose(U, s, V)
                    F[p] = Fp
                    A[p] = phys.affine(Fp, U, V, s, C[p])

        # ---------------------------------------------------------------- kernels
        @ti.kernel
        def begin_step():
            """Start an env step: the warm-start rotations from a full SVD of F, then the first substep's
            constitutive update (every later substep's runs in the previous substep's particle loop)."""
            for p in range(n_p[None]):
                _U, _sig, V = ti.svd(F[p])
                Vr[p] = V
            for p in range(n_p[None]):
                if p % LANES == 0:
                    constitutive_group(p)

        @ti.kernel
        def substep(t_now: ti.f32, last: ti.i32):
            """One substep in three loops, one of them parallel on CPU (a parallel loop costs a thread-pool
            dispatch, measured 40-60 us on a 2-core VM, about the work of a 1000-particle loop):

            1. serial: clear the previous substep's touched box, scatter every particle (a serialized loop:
               Taichi then demotes the atomics to plain adds, ~3x faster than parallel atomics on CPU, and
               the sums come in one order: bitwise deterministic) and record the new touched box;
            2. serial on CPU: the grid operation over the touched box (a few thousand nodes);
            3. parallel, per particle: gather, advect, and (unless ``last``) the next substep's constitutive
               update, so that no loop of its own is needed for it.

            The grid keeps the last substep's values between env steps (the next substep clears them).
            """
            blo, ext = phys.box_extent(bbox)
            ti.loop_config(serialize=serial)  # the previous substep's box: cheaper than a thread-pool dispatch
            for tt in range(ext[0] * ext[1] * ext[2]):
                grid[phys.box_node(blo, ext, tt)] = ti.Vector.zero(ti.f32, 4)
            lo = ti.Vector([n, n, n])
            hi = ti.Vector([-1, -1, -1])
            if ti.static(serial):
                ti.loop_config(serialize=True)
                for p in range(n_p[None]):
                    base = phys.scatter(grid, x[p], v[p], A[p])
                    lo = ti.min(lo, base)
                    hi = ti.max(hi, base + 2)
                phys.box_store(bbox, lo, hi)
            else:
                phys.box_store(bbox, lo, hi)  # empty
                for p in range(n_p[None]):
                    phys.box_include(bbox, phys.scatter(grid, x[p], v[p], A[p]))
            nlo, next_ = phys.box_extent(bbox)
            ti.loop_config(serialize=serial)  # a few thousand nodes: cheaper than a thread-pool dispatch
            for tt in range(next_[0] * next_[1] * next_[2]):
                I = phys.box_node(nlo, next_, tt)
                gv = grid[I]
                if gv[3] > 0:
                    vel = phys.node_velocity(I, gv, t_now)
                    grid[I] = ti.Vector([vel[0], vel[1], vel[2], gv[3]])
            for p in range(n_p[None]):
                if p % LANES == 0:  # LANES particles per iteration (Taichi's CPU tasks of 512 hold whole groups)
                    for k in ti.static(range(LANES)):
                        if p + k < n_p[None]:
                            new_v, new_C = phys.gather(grid, x[p + k])
                            x[p + k], v[p + k], C[p + k] = phys.advance(x[p + k], new_v, new_C, bad)
                    if last == 0:
                        constitutive_group(p)

        @ti.kernel
        def check_state() -> ti.i32:
            """Count particles with a non-finite state or a position outside the unit cube."""
            cnt = 0
            for p in range(n_p[None]):
                s = x[p].sum() + v[p].sum() + F[p].sum() + C[p].sum()
                if not (ti.abs(s) < 1e30) or x[p].min() < 0.0 or x[p].max() > 1.0:
                    cnt += 1
            return cnt

        @ti.kernel
        def clear_all():
            for I in ti.grouped(grid):
                grid[I] = ti.Vector.zero(ti.f32, 4)
            for d in ti.static(range(3)):
                bbox[d] = 0
                bbox[3 + d] = -1
            bad[0] = 0
            bad[1] = 0

        @ti.kernel
        def reset_bad():
            bad[0] = 0
            bad[1] = 0

        self._begin_step = begin_step
        self._substep = substep
        self.check_state = check_state
        self.clear_all = clear_all
        self.reset_bad = reset_bad
        self.owner = None  # the Simulator whose state is currently in the fields

    def substeps(self, n_sub: int, dt: float) -> None:
        """Run ``n_sub`` substeps. The tool field holds the env-step start poses and velocities;
        substep s uses the tool poses at time (s + 1) * dt."""
        self._begin_step()
        for s in range(n_sub):
            self._substep((s + 1) * dt, int(s == n_sub - 1))

    def set_tools(self, arrays: dict) -> None:
        """Load the static tool data of ``ToolTable.kernel_arrays()`` (no recompile)."""
        st = self.statics
        st["tool_kind"].from_numpy(arrays["kind"])
        st["tool_geo"].from_numpy(arrays["geo"])
        st["tool_n_prims"].from_numpy(arrays["n_prims"])
        st["tool_bound2"].from_numpy(arrays["bound2"])
        st["tool_fric"].from_numpy(arrays["friction"])
        st["n_tools"][None] = int(arrays["n_tools"])

    def set_particles(self, x: np.ndarray, v: np.ndarray, F: np.ndarray, C: np.ndarray) -> None:
        """Load a particle state (N, 3), (N, 3), (N, 3, 3), (N, 3, 3); clears the grid."""
        n = x.shape[0]
        m = self.max_particles

        def pad(a: np.ndarray, shape: tuple) -> np.ndarray:
            out = np.zeros((m, *shape), dtype=np.float32)
            out[:n] = a
            return out

        self.x.from_numpy(pad(x, (3,)))
        self.v.from_numpy(pad(v, (3,)))
        self.F.from_numpy(pad(F, (3, 3)))
        self.C.from_numpy(pad(C, (3, 3)))
        self.n_p[None] = n
        self.clear_all()

    def get_particles(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        n = int(self.n_p[None])
        return (self.x.to_numpy()[:n], self.v.to_numpy()[:n], self.F.to_numpy()[:n], self.C.to_numpy()[:n])
