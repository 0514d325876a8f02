"""Registers the 'push' skill: cardinality and tool are known here without importing torch or taichi."""

from dataclasses import dataclass

from pasta.core import SkillSpec
from pasta.plugins import hookimpl
from pasta_skill_push.tool import PUSHER

SPEC = SkillSpec(name="push", n_in=1, n_out=1, tool="pusher", description="push one dough piece to a new place with the pusher")


@dataclass
class PushConfig:
    """Settings of the push skill (distances in metres of the unit-cube workspace).

    Attributes:
        max_steps: env-step limit of one execution.
        gap: distance between the pusher face and the piece's trailing side at the approach pose.
        sink: how far the pusher bottom goes below the piece bottom (it must not slide over the floor band).
        clearance: the pusher footprint at the approach pose keeps this distance from other dough.
        slow_distance: the push slows down linearly over this last distance (the dough slides on).
        min_speed: slowest push, as a fraction of the full 0.01 per env step.
        tolerance: done when the centroid is this close to the target along the push line.
        target_x_min, target_x_max, target_z_min, target_z_max: expert sampling box of target centroids.
        min_distance: expert sampling: targets at least this far from the piece centroid.
        max_distance: expert sampling: targets at most this far from the piece centroid (0: anywhere in the
            box); the ``nudge`` demonstrations' short corrections.
        max_face_slide: heuristic approach only: the paddle may also slide along its face by up to this
            (while still spanning the piece) to clear neighbouring dough before the face is turned away
            from the push direction (a turned face let a piece slide off it: crs seed 1012, where a cut
            left 1 cm less room than in the recorded run). The expert's approach does not slide.
        align_after: heuristic only: after the pusher has moved this far along the push line it turns
            its face back square to the line (dyaw), in case the approach had to turn it; 0: never.
    """

    max_steps: int = 80
    gap: float = 0.008
    sink: float = 0.005
    clearance: float = 0.006
    slow_distance: float = 0.1
    min_speed: float = 0.1
    tolerance: float = 0.003
    target_x_min: float = 0.22
    target_x_max: float = 0.32
    target_z_min: float = 0.3
    target_z_max: float = 0.7
    min_distance: float = 0.08
    max_distance: float = 0.0
    max_face_slide: float = 0.04
    align_after: float = 0.02


@hookimpl
def pasta_register_skills(register):
    register(spec=SPEC, factory="pasta_skill_push.skill:PushSkill", config=PushConfig)


@hookimpl
def pasta_register_tools(register):
    register(spec=PUSHER)
