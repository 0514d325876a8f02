"""The gripper, the gather skill's tool: pure data, registered by this package's plugin module.

Two fingers 0.04 (x) x 0.08 (y) x 0.14 (z) either side of the tool centre; the gap between their inner
faces (the aperture) starts at 0.3 and an ``open`` action changes it (0.01 per env step at 1, each finger
half of that). Action ``(dx, dy, dz, dyaw, open)``: world translation 0.01, yaw 0.025 rad.
"""

from __future__ import annotations

from pasta.core.tool import ActionChannel, FingerPair, ToolSpec

# 4 cm thick (2.5 grid cells): 2 cm fingers let dough through while closing (three lumps squeezed to a
# 6.5 cm gap ended 11 cm long; 8.6 cm with 4 cm fingers standing on the floor, 7.6 cm reaching below it)
FINGER_HALF = (0.02, 0.04, 0.07)
OPEN_APERTURE = 0.3
GRIPPER_STEP = 0.01  # metres per env step at action 1 (translation and aperture)
GRIPPER_YAW_STEP = 0.025
GRIPPER_PARK = (0.3, 0.8, 0.88)

GRIPPER = ToolSpec(
    "gripper",
    description="a parallel gripper: two fingers whose gap is an action component",
    primitives=(FingerPair(half=FINGER_HALF, aperture=OPEN_APERTURE, min_aperture=0.0, max_aperture=OPEN_APERTURE),),
    action=(ActionChannel("x", GRIPPER_STEP), ActionChannel("y", GRIPPER_STEP), ActionChannel("z", GRIPPER_STEP),
            ActionChannel("yaw", GRIPPER_YAW_STEP), ActionChannel("open", GRIPPER_STEP)),
    park=GRIPPER_PARK,
    friction=1.0,
    color="tab:orange",
)
