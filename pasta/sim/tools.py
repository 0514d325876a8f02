"""Tools as simulator data: a :class:`ToolTable` turns registered :class:`~pasta.core.ToolSpec` s into the
kernel's runtime arrays, allowed pose boxes and surface-point templates (numpy only, no taichi).

Every tool is a union of analytic SDF primitives in its own frame. A tool's state is a row
``(x, y, z, yaw, spin, aperture)``: its centre, a yaw about the world y axis, a spin about its local z
axis (rolling tools only; it turns the quaternion and the surface points, the SDF is treated as
round) and the gap of its finger pair (0 without one).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from pasta.core.errors import ConfigError, InputError
from pasta.core.tool import MAX_PRIMITIVES, Box, Capsule, FingerPair, ToolSpec, WedgeBlade

#: tool slots of the kernel (a simulator holds at most this many tools)
MAX_TOOLS = 8
#: primitive slots per tool
MAX_PRIMS = MAX_PRIMITIVES
#: kernel ids of the primitive kinds
KIND_IDS = {"box": 0, "wedge_blade": 1, "capsule": 2, "finger_pair": 3}
#: floats per primitive slot: offset (3), size (3: half extents, or radius / half length), wedge cos / sin
GEO = 8
#: margin added to each tool's bounding radius before the kernel skips far grid nodes
BOUND_MARGIN = 0.03
#: state row of one tool
STATE_COLS = ("x", "y", "z", "yaw", "spin", "aperture")


class NumpyOps:
    """The array operations :meth:`ToolTable.motion` needs, on numpy (the simulator's); ``pasta.sim.grad`` passes
    torch ones, so one piece of kinematics serves the forward and the differentiable simulator."""

    cos = staticmethod(math.cos)
    sin = staticmethod(math.sin)
    vec = staticmethod(np.array)  # a list of scalars -> a vector
    clip = staticmethod(np.clip)  # (array or scalar, lo, hi)

    @staticmethod
    def zeros3() -> np.ndarray:
        return np.zeros(3)

    @staticmethod
    def add_y(v: np.ndarray, value: Any) -> np.ndarray:
        v[1] += value
        return v


def yaw_quat(yaw: float) -> np.ndarray:
    """Quaternion (w, x, y, z) of a rotation by ``yaw`` about +y."""
    return np.array([math.cos(yaw / 2), 0.0, math.sin(yaw / 2), 0.0])


def quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return np.array([
        w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
        w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
        w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
        w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
    ])


def tool_quat(yaw: float, spin: float) -> np.ndarray:
    """Orientation (w, x, y, z): yaw about world y, then spin about the tool's local z axis."""
    q = quat_mul(yaw_quat(yaw), np.array([math.cos(spin / 2), 0.0, 0.0, math.sin(spin / 2)]))
    return q / np.linalg.norm(q)


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    w, x, y, z = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def _face_grid(centre, half, axis: int, sign: float, n: int) -> list[tuple[float, float, float]]:
    """n x n points on the face of a box normal to ``axis`` on side ``sign``."""
    a, b = [d for d in range(3) if d != axis]
    out = []
    for u in np.linspace(-half[a], half[a], n):
        for v in np.linspace(-half[b], half[b], n):
            p = [0.0, 0.0, 0.0]
            p[axis], p[a], p[b] = sign * half[axis], u, v
            out.append(tuple(c + q for c, q in zip(centre, p)))
    return out


def generated_template(spec: ToolSpec) -> tuple[np.ndarray, np.ndarray]:
    """Surface points of a tool without explicit ``surface_points``: (T, 3) float64 in the tool frame at
    aperture 0, and (T,) side in {-1, 0, 1}: a finger point moves by side * aperture / 2 along local x."""
    pts: list[tuple[float, float, float]] = []
    side: list[float] = []
    for p in spec.primitives:
        o = p.offset
        if isinstance(p, Capsule):  # 10 angles x 10 positions along the axis
            for a in np.linspace(0, 2 * math.pi, 10, endpoint=False):
                for z in np.linspace(-p.half_length, p.half_length, 10):
                    pts.append((o[0] + p.radius * math.cos(a), o[1] + p.radius * math.sin(a), o[2] + z))
            side += [0.0] * 100
        elif isinstance(p, FingerPair):  # inner and outer face of each finger, 5 x 5 each
            for s in (-1.0, 1.0):
                c = (o[0] + s * p.half[0], o[1], o[2])
                for sign in (-1.0, 1.0):
                    face = _face_grid(c, p.half, 0, sign, 5)
                    pts += face
                    side += [s] * len(face)
        elif isinstance(p, WedgeBlade):  # both x faces, narrowed by the wedge near the edge
            hx, hy, hz = p.half
            tan = math.tan(math.radians(p.half_angle))
            for sx in (-1.0, 1.0):
                for y in np.linspace(-hy, hy, 5):
                    half = min(hx, (y + hy) * tan)
                    for z in np.linspace(-hz, hz, 10):
                        pts.append((o[0] + sx * half, o[1] + y, o[2] + z))
            side += [0.0] * 100
        elif isinstance(p, Box):  # 4 x 4 on each of the six faces
            for axis in range(3):
                for sign in (-1.0, 1.0):
                    pts += _face_grid(o, p.half, axis, sign, 4)
            side += [0.0] * 96
    return np.asarray(pts, dtype=np.float64), np.asarray(side, dtype=np.float64)


class ToolTable:
    """The tools of one simulator, in its order, and everything derived from their specs.

    Args:
        specs: the tools, 1..MAX_TOOLS distinct names, each with geometry.
        friction: ``{name: friction}`` overrides of ``ToolSpec.friction`` (names must be in ``specs``).
        dx: grid spacing (the allowed pose box keeps tools 3 cells inside the walls).
    """

    def __init__(self, specs: Sequence[ToolSpec], friction: Mapping[str, float], dx: float) -> None:
        specs = list(specs)
        for s in specs:
            if not isinstance(s, ToolSpec):
                raise ConfigError(f"Simulator tools must be pasta.core.ToolSpec objects, got {s!r}")
            if not s.simulated:
                raise ConfigError(f"tool '{s.name}' has no geometry (a name-only tool); it cannot be simulated")
        names = tuple(s.name for s in specs)
        if not names:
            raise ConfigError("Simulator needs at least one tool (none registered or given)")
        if len(set(names)) != len(names):
            raise ConfigError(f"Simulator tools must have distinct names, got {list(names)}")
        if len(names) > MAX_TOOLS:
            raise ConfigError(f"Simulator supports at most {MAX_TOOLS} tools (kernel slots), got {len(names)}: {list(names)}")
        unknown = sorted(set(friction) - set(names))
        if unknown:
            raise ConfigError(f"sim.tool_friction names unknown tools {unknown}; tools: {', '.join(names)}")
        self.names = names
        self.specs = {s.name: s for s in specs}
        self.index = {n: i for i, n in enumerate(names)}
        self.friction = {n: float(friction.get(n, self.specs[n].friction)) for n in names}
        self.dx = dx
        self.templates: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        for s in specs:
            if s.surface_points is not None:
                pts = np.asarray(s.surface_points, dtype=np.float64)
                self.templates[s.name] = (pts, np.zeros(len(pts)))
            else:
                self.templates[s.name] = generated_template(s)

    def __len__(self) -> int:
        return len(self.names)

    def spec(self, name: str) -> ToolSpec:
        if name not in self.specs:
            raise InputError(f"unknown tool '{name}'; tools: {', '.join(self.names)}")
        return self.specs[name]

    def bounds(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """(lo, hi) box the tool centre is clamped to: 3 cells inside the walls; y >= the tool's lowest
        allowed centre height (``ToolSpec.lowest_centre``)."""
        lo = np.full(3, 3 * self.dx)
        hi = np.full(3, 1.0 - 3 * self.dx)
        lo[1] = self.spec(name).lowest_centre
        return lo, hi

    def motion(self, name: str, cur: Any, a: Any, T: float, ops: Any = NumpyOps) -> tuple:
        """One env step of tool ``name`` from state row ``cur`` (x, y, z, yaw, spin, aperture) under the action
        ``a`` (already clipped to [-1, 1] and scaled, one value per leading channel), over an env step of ``T``
        seconds: returns (linear velocity (3), angular velocity (3, world frame), yaw rate, aperture rate, the
        new state row (6)). Channels: x, y, z world translation; yaw about +y; roll by that angle about the
        local z axis (the tool moves angle * radius along its local x and spins); slide along local x; open:
        aperture change (clamped to the finger pair's range). Translations are clamped to :meth:`bounds`.
        ``ops``: the array operations (numpy, or torch for gradients)."""
        spec = self.spec(name)
        ch = dict(zip(spec.channels, a))
        yaw, spin = cur[3], cur[4]
        world = ops.vec([ch.get("x", 0.0), ch.get("y", 0.0), ch.get("z", 0.0)])
        dyaw = ch.get("yaw", 0.0)
        omega = ops.zeros3()
        if "roll" in spec.channels or "slide" in spec.channels:
            roll = ch.get("roll", 0.0)
            d = ops.vec([ops.cos(yaw), 0.0, -ops.sin(yaw)])  # local +x in world
            # written as one sum, as the roller always did: d * (roll * r + slide) + world
            delta = d * ((roll * spec.roll_radius if "roll" in spec.channels else 0.0) + ch.get("slide", 0.0)) + world
            if "roll" in spec.channels:
                axis = ops.vec([ops.sin(yaw), 0.0, ops.cos(yaw)])  # local +z in world
                omega = -roll / T * axis
                spin = spin - roll
        else:
            delta = world
        lo, hi = self.bounds(name)
        target = ops.clip(cur[:3] + delta, lo, hi)
        omega = ops.add_y(omega, dyaw / T)
        aperture = cur[5]
        if "open" in ch:
            a_lo, a_hi = self.aperture_range(name)
            aperture = ops.clip(cur[5] + ch["open"], a_lo, a_hi)
        new = ops.vec([target[0], target[1], target[2], yaw + dyaw, spin, aperture])
        return (target - cur[:3]) / T, omega, dyaw / T, (aperture - cur[5]) / T, new

    def park_row(self, name: str) -> np.ndarray:
        """(6,) state row of the parked tool: its park centre, yaw 0, spin 0, its starting aperture."""
        s = self.spec(name)
        assert s.park is not None  # ToolSpec requires it of a tool with primitives
        return np.array([*s.park, 0.0, 0.0, s.default_aperture], dtype=np.float64)

    def aperture_range(self, name: str) -> tuple[float, float]:
        fp = self.spec(name).finger_pair
        return (0.0, 0.0) if fp is None else (fp.min_aperture, fp.max_aperture)  # type: ignore[return-value]  # _check set max_aperture

    def kernel_arrays(self) -> dict[str, np.ndarray | np.int32]:
        """The engine's static tool fields: kind (MAX_TOOLS, MAX_PRIMS) int32, geo (MAX_TOOLS, MAX_PRIMS,
        GEO) float32, n_prims (MAX_TOOLS,) int32, bound2 (MAX_TOOLS,) float32 (squared skip radius),
        friction (MAX_TOOLS,) float32, n_tools () int32."""
        kind = np.zeros((MAX_TOOLS, MAX_PRIMS), np.int32)
        geo = np.zeros((MAX_TOOLS, MAX_PRIMS, GEO), np.float32)
        n_prims = np.zeros(MAX_TOOLS, np.int32)
        bound2 = np.zeros(MAX_TOOLS, np.float32)
        fric = np.zeros(MAX_TOOLS, np.float32)
        for t, name in enumerate(self.names):
            s = self.specs[name]
            n_prims[t] = len(s.primitives)
            # squared in double, rounded to float32 once: the same value a Python constant would give
            bound2[t] = (s.bound_radius + BOUND_MARGIN) ** 2
            fric[t] = self.friction[name]
            for k, p in enumerate(s.primitives):
                kind[t, k] = KIND_IDS[p.kind]
                geo[t, k, 0:3] = p.offset
                if isinstance(p, Capsule):
                    geo[t, k, 3:5] = (p.radius, p.half_length)
                else:
                    geo[t, k, 3:6] = p.half  # type: ignore[attr-defined]  # every kind but the capsule has one
                if isinstance(p, WedgeBlade):
                    a = math.radians(p.half_angle)
                    geo[t, k, 6:8] = (math.cos(a), math.sin(a))
        return {"kind": kind, "geo": geo, "n_prims": n_prims, "bound2": bound2, "friction": fric,
                "n_tools": np.int32(len(self.names))}

    def surface_points(self, name: str, row: np.ndarray) -> np.ndarray:
        """(T, 3) float32 surface points of tool ``name`` with state row (x, y, z, yaw, spin, aperture)."""
        pts, side = self.templates[name]
        if side.any():
            pts = pts.copy()
            pts[:, 0] += side * (row[5] / 2)
        rot = quat_to_matrix(tool_quat(row[3], row[4]))
        return (pts @ rot.T + np.asarray(row[:3], dtype=np.float64)).astype(np.float32)


def tool_shapes(spec: ToolSpec, pose: np.ndarray, aperture: float | None = None) -> list[tuple[str, str, tuple, np.ndarray, np.ndarray]]:
    """Viewer shapes of a tool at ``pose`` (7,) (position + quaternion w, x, y, z): a list of
    (entity name, ``"cube"`` | ``"cylinder"``, full size (3,), world centre (3,), quaternion (4,)).
    One shape keeps the tool's name; several are named ``name.0``, ``name.1``, ..."""
    pose = np.asarray(pose, dtype=np.float64)
    quat = pose[3:7]
    rot = quat_to_matrix(quat)
    shapes = spec.draw(aperture)
    out = []
    for i, (kind, size, offset) in enumerate(shapes):
        name = spec.name if len(shapes) == 1 else f"{spec.name}.{i}"
        centre = pose[:3] + rot @ np.asarray(offset, dtype=np.float64) if any(offset) else pose[:3].copy()
        out.append((name, kind, tuple(size), centre, quat))
    return out
