"""The spatula (the lift skill's tool) and the raised cutting board (a static obstacle): pure data.

Spatula: a flat plate 0.14 x 0.03 x 0.14 (a thin box, friction 50 as in the PASTA release) moved in
x, y, z (0.01 per env step at 1). Board: a box 0.3 (x) x 0.05 (y) x 0.32 (z) without action channels;
tasks put it at :data:`BOARD_POSE` (its registered stand pose, ``ToolSpec.stand``: top at y =
:data:`BOARD_TOP`, over the left of the workspace), and it waits at its parking place, high above the
dough, everywhere else. Other plugins (the roll skill, the board tasks) read the pose from the
registered spec, not from this module.

The simulator's tools are kinematic and do not collide with each other: the spatula sets the dough down
by sinking through the board's top (the kinematic stand-in for tilting the dough off; the board's
contact keeps the dough on top while the plate passes below it).
"""

from __future__ import annotations

import numpy as np

from pasta.core.tool import ActionChannel, Box, ToolSpec

SPATULA_HALF = (0.07, 0.015, 0.07)
SPATULA_STEP = 0.01  # metres per env step at action 1
SPATULA_PARK = (0.7, 0.85, 0.5)

BOARD_HALF = (0.15, 0.025, 0.16)
#: where tasks put the board: centre x 0.3 (x 0.15-0.45), z 0.5, resting on the floor (y 0.02)
BOARD_POSE = (0.3, 0.02 + BOARD_HALF[1], 0.5)
BOARD_TOP = BOARD_POSE[1] + BOARD_HALF[1]
BOARD_PARK = (0.3, 0.9, 0.5)


def _spatula_points() -> tuple[tuple[float, float, float], ...]:
    """10 x 10 points on the top face (what carries the dough)."""
    hx, hy, hz = SPATULA_HALF
    return tuple((float(x), hy, float(z)) for x in np.linspace(-hx, hx, 10) for z in np.linspace(-hz, hz, 10))


SPATULA = ToolSpec(
    "spatula",
    description="a flat plate (high friction) that carries dough, moved in x, y, z",
    primitives=(Box(half=SPATULA_HALF),),
    action=(ActionChannel("x", SPATULA_STEP), ActionChannel("y", SPATULA_STEP), ActionChannel("z", SPATULA_STEP)),
    park=SPATULA_PARK,
    # the plate may sink below the floor: the lift starts with it under dough that rests on the floor
    min_height=0.0,
    friction=50.0,
    surface_points=_spatula_points(),
    color="tab:brown",
)

BOARD = ToolSpec(
    "board",
    description="a raised cutting board (static obstacle, placed by tasks)",
    primitives=(Box(half=BOARD_HALF),),
    park=BOARD_PARK,
    stand=BOARD_POSE,
    friction=2.0,  # as the floor's spreading area (raising it to 10 changed no roll on the board)
    color="tan",
)
