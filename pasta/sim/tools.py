"""Rigid tools: geometry, action layout, parking poses and surface-point templates (numpy only).

Every tool is an analytic SDF in its own frame. A tool pose is a position (the tool's centre) and a
yaw about the world y axis (the roller also carries a spin angle about its own axis, for its
quaternion and surface points; the SDF is axisymmetric).

Tool frames (yaw = 0):

- ``knife``: a blade thin along x (0.05 thick), 0.12 long along z, 0.2 tall along y, with a 60 degree
  wedge edge pointing down; the tip is ``KNIFE_HALF[1]`` below the centre. Cuts in the y-z plane.
- ``pusher``: a box 0.03 (x) x 0.1 (y) x 0.2 (z): a paddle that pushes along x.
- ``roller``: a capsule of radius 0.03 whose 0.15-long axis is along z; rolling moves it along x.
"""

from __future__ import annotations

import math

import numpy as np

TOOL_NAMES: tuple[str, ...] = ("knife", "pusher", "roller")
#: action layout per tool; every component is in [-1, 1] and scaled by TOOL_ACTION_SCALES
#: knife (dx, dy); pusher (dx, dy, dz, dyaw); roller (roll, dyaw, dy, slide)
TOOL_ACTION_DIMS: dict[str, int] = {"knife": 2, "pusher": 4, "roller": 4}
TOOL_ACTION_SCALES: dict[str, tuple[float, ...]] = {
    "knife": (0.015, 0.015),
    "pusher": (0.01, 0.01, 0.01, 0.025),
    "roller": (0.7, 0.005, 0.005, 0.005),
}

KNIFE_HALF = (0.025, 0.1, 0.06)  # half extents of the blade box
KNIFE_WEDGE_HALF_ANGLE = math.radians(30.0)
KNIFE_TIP_DEPTH = 0.05  # how far below y = 0 the (virtual) knife tip may go
PUSHER_HALF = (0.015, 0.05, 0.1)
ROLLER_RADIUS = 0.03
ROLLER_HALF_LENGTH = 0.075

#: bounding-sphere radius of each tool around its centre (used to skip far grid nodes)
TOOL_BOUND_RADIUS = {
    "knife": math.sqrt(sum(h * h for h in KNIFE_HALF)),
    "pusher": math.sqrt(sum(h * h for h in PUSHER_HALF)),
    "roller": ROLLER_RADIUS + ROLLER_HALF_LENGTH,
}

#: where unused tools wait: high up, near the back corner, far from any dough
PARK_POSES: dict[str, tuple[float, float, float]] = {
    "knife": (0.15, 0.8, 0.12),
    "pusher": (0.45, 0.8, 0.12),
    "roller": (0.75, 0.8, 0.12),
}


def tool_bounds(name: str, dx: float) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi) box that the tool centre is clamped to: inside the side walls; y >= the tool's
    lowest point at y = 0 (pusher bottom, roller axis at y >= radius) or 0.05 below (knife tip)."""
    lo = np.full(3, 3 * dx)
    hi = np.full(3, 1.0 - 3 * dx)
    # lowest centre height: the pusher and roller bottoms may reach y = 0; the knife tip may go
    # 0.05 below it, so that the blade is at full thickness (0.05) at the floor and cuts through
    lo[1] = {"knife": KNIFE_HALF[1] - KNIFE_TIP_DEPTH, "pusher": PUSHER_HALF[1], "roller": ROLLER_RADIUS}[name]
    return lo, hi


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


def _templates() -> dict[str, np.ndarray]:
    """~100 surface points per tool in its local frame, fixed forever."""
    out = {}
    # knife: 2 faces x 50 points (10 along z x 5 along y) on the lower part of the blade
    hx, hy, hz = KNIFE_HALF
    zs = np.linspace(-hz, hz, 10)
    ys = np.linspace(-hy, -hy + 0.1, 5)
    pts = []
    for sx in (-1.0, 1.0):
        for y in ys:
            # the wedge narrows the blade near the tip
            half = min(hx, (y + hy) * math.tan(KNIFE_WEDGE_HALF_ANGLE))
            for z in zs:
                pts.append((sx * half, y, z))
    out["knife"] = np.asarray(pts)
    # pusher: both x faces, 5 (y) x 10 (z) each
    hx, hy, hz = PUSHER_HALF
    pts = [(sx * hx, y, z) for sx in (-1.0, 1.0) for y in np.linspace(-hy, hy, 5) for z in np.linspace(-hz, hz, 10)]
    out["pusher"] = np.asarray(pts)
    # roller: 10 angles x 10 positions along the axis on the cylinder
    ang = np.linspace(0, 2 * math.pi, 10, endpoint=False)
    zs = np.linspace(-ROLLER_HALF_LENGTH, ROLLER_HALF_LENGTH, 10)
    out["roller"] = np.asarray([(ROLLER_RADIUS * math.cos(a), ROLLER_RADIUS * math.sin(a), z) for a in ang for z in zs])
    return {k: v.astype(np.float64) for k, v in out.items()}


TOOL_TEMPLATES: dict[str, np.ndarray] = _templates()


def tool_surface_points(name: str, position: np.ndarray, yaw: float, spin: float = 0.0) -> np.ndarray:
    """(T, 3) float32 surface points of tool ``name`` at the given pose."""
    rot = quat_to_matrix(tool_quat(yaw, spin))
    return (TOOL_TEMPLATES[name] @ rot.T + np.asarray(position, dtype=np.float64)).astype(np.float32)
