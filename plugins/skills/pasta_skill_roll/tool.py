"""The roller, the roll skill's tool: pure data, registered by this package's plugin module.

A capsule of radius 0.03 whose 0.15-long axis is along local z. Action (roll, dyaw, dy, slide): rolling
by angle a (0.7 rad at 1) moves it a * radius along local x and spins it; dyaw 0.005 rad, dy 0.005,
slide 0.005 along local x. A 3-vector means slide = 0.
"""

from __future__ import annotations

import math

import numpy as np

from pasta.core.tool import ActionChannel, Capsule, ToolSpec

ROLLER_RADIUS = 0.03
ROLLER_HALF_LENGTH = 0.075
ROLLER_ROLL_STEP = 0.7  # radians per env step at action 1
ROLLER_STEP = 0.005  # metres (or radians of yaw) per env step at action 1, other components
ROLLER_PARK = (0.75, 0.8, 0.12)


def _surface_points() -> tuple[tuple[float, float, float], ...]:
    """10 angles x 10 positions along the axis on the cylinder."""
    ang = np.linspace(0, 2 * math.pi, 10, endpoint=False)
    zs = np.linspace(-ROLLER_HALF_LENGTH, ROLLER_HALF_LENGTH, 10)
    return tuple((float(ROLLER_RADIUS * math.cos(a)), float(ROLLER_RADIUS * math.sin(a)), float(z)) for a in ang for z in zs)


ROLLER = ToolSpec(
    "roller",
    description="a rolling pin (capsule), rolled along its local x, turned, lifted and slid",
    primitives=(Capsule(radius=ROLLER_RADIUS, half_length=ROLLER_HALF_LENGTH),),
    action=(ActionChannel("roll", ROLLER_ROLL_STEP), ActionChannel("yaw", ROLLER_STEP), ActionChannel("y", ROLLER_STEP),
            ActionChannel("slide", ROLLER_STEP)),
    required_action=3,
    park=ROLLER_PARK,
    friction=0.9,
    surface_points=_surface_points(),
    color="tab:purple",
)
