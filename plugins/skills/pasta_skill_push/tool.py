"""The pusher, the push skill's tool: pure data, registered by this package's plugin module.

A box paddle 0.03 (x) x 0.1 (y) x 0.2 (z) that pushes along x. Action: world (dx, dy, dz) 0.01 per env
step at 1 and yaw 0.025 rad.
"""

from __future__ import annotations

import numpy as np

from pasta.core.tool import ActionChannel, Box, ToolSpec

PUSHER_HALF = (0.015, 0.05, 0.1)
PUSHER_STEP = 0.01  # metres per env step at action 1
PUSHER_YAW_STEP = 0.025  # radians per env step at action 1
PUSHER_PARK = (0.45, 0.8, 0.12)


def _surface_points() -> tuple[tuple[float, float, float], ...]:
    """Both x faces, 5 (y) x 10 (z) points each."""
    hx, hy, hz = PUSHER_HALF
    return tuple((float(sx * hx), float(y), float(z)) for sx in (-1.0, 1.0)
                 for y in np.linspace(-hy, hy, 5) for z in np.linspace(-hz, hz, 10))


PUSHER = ToolSpec(
    "pusher",
    description="a box paddle, moved in x, y, z and turned about y",
    primitives=(Box(half=PUSHER_HALF),),
    action=(ActionChannel("x", PUSHER_STEP), ActionChannel("y", PUSHER_STEP), ActionChannel("z", PUSHER_STEP),
            ActionChannel("yaw", PUSHER_YAW_STEP)),
    park=PUSHER_PARK,
    friction=5.0,
    surface_points=_surface_points(),
    color="tab:green",
)


def pusher_bounds(dx: float = 1.0 / 64) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi) box the simulator clamps the pusher centre to: 3 grid cells inside the walls and
    y >= ``PUSHER.lowest_centre`` (the paddle bottom at y = 0)."""
    lo = np.full(3, 3 * dx)
    hi = np.full(3, 1.0 - 3 * dx)
    lo[1] = PUSHER.lowest_centre
    return lo, hi
