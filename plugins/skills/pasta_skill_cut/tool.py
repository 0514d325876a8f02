"""The knife, the cut skill's tool: pure data (numpy only), registered by this package's plugin module.

A blade thin along x (0.05 thick), 0.12 long along z and 0.2 tall along y, with a 60 degree wedge edge
pointing down; the tip is ``KNIFE_HALF[1]`` below the centre. It cuts in the y-z plane. Action: world
(dx, dy), 0.015 per env step at 1.
"""

from __future__ import annotations

import math

import numpy as np

from pasta.core.tool import ActionChannel, ToolSpec, WedgeBlade

KNIFE_HALF = (0.025, 0.1, 0.06)  # half extents of the blade box
KNIFE_WEDGE_DEGREES = 30.0  # half angle of the wedge edge
KNIFE_WEDGE_HALF_ANGLE = math.radians(KNIFE_WEDGE_DEGREES)
KNIFE_TIP_DEPTH = 0.05  # how far below y = 0 the (virtual) knife tip may go
KNIFE_STEP = 0.015  # metres per env step at action 1, both components
KNIFE_PARK = (0.15, 0.8, 0.12)


def _surface_points() -> tuple[tuple[float, float, float], ...]:
    """2 faces x 50 points (10 along z x 5 along y) on the lower part of the blade; the wedge narrows
    the blade near the tip."""
    hx, hy, hz = KNIFE_HALF
    zs = np.linspace(-hz, hz, 10)
    ys = np.linspace(-hy, -hy + 0.1, 5)
    pts = []
    for sx in (-1.0, 1.0):
        for y in ys:
            half = min(hx, (y + hy) * math.tan(KNIFE_WEDGE_HALF_ANGLE))
            for z in zs:
                pts.append((float(sx * half), float(y), float(z)))
    return tuple(pts)


KNIFE = ToolSpec(
    "knife",
    description="a wedge-edged blade, moved in x and y",
    primitives=(WedgeBlade(half=KNIFE_HALF, half_angle=KNIFE_WEDGE_DEGREES),),
    action=(ActionChannel("x", KNIFE_STEP), ActionChannel("y", KNIFE_STEP)),
    park=KNIFE_PARK,
    # the tip may go KNIFE_TIP_DEPTH below the floor, so that the blade is at full thickness (0.05) at the
    # floor and cuts through
    min_height=KNIFE_HALF[1] - KNIFE_TIP_DEPTH,
    friction=0.0,
    surface_points=_surface_points(),
    color="tab:red",
)
