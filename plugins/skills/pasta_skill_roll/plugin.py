"""Registers the 'roll' skill: cardinality and tool are known here without importing torch or taichi."""

from dataclasses import dataclass

from pasta.core import SkillSpec
from pasta.plugins import hookimpl
from pasta_skill_roll.tool import ROLLER

SPEC = SkillSpec(name="roll", n_in=1, n_out=1, tool="roller", description="roll one dough piece flat with the roller")


@dataclass
class RollConfig:
    """Settings of the roll skill (distances in metres of the unit-cube workspace).

    Attributes:
        max_steps: env-step limit of one execution.
        clearance: roller bottom above the piece top at the approach pose.
        height_min, height_max: expert sampling: the gap left under the roller (the rolled thickness).
        width: expert sampling: assumed rolled width (z) when turning the piece volume into a length.
        length_min_factor, length_max_factor: expert sampling: target length = volume / (height * width)
            times U(min, max).
        turn_inset: the roller turns this far (in radii) inside the ends of the allowed span.
        length_tolerance: done when the rolled length is within this of the target.
        thickness_tolerance: the heuristic is done only when the piece is at most this much thicker
            than the goal.
        min_passes: done only after this many passes at the final height.
        max_passes: done after this many passes at the final height even if the piece is short or thick.
        springback: the rolled dough ends this much thinner than the gap under the roller; the heuristic
            adds it back to the goal's measured thickness. Measured on 41 recorded expert rolls (task
            test sets): the dough ends ~2.7 mm THICKER than the gap (median; thickness = 95th minus 1st
            percentile of y; 0.5-3.7 mm). Yet 0 is the default: -0.0027 (the expert's gap on average)
            pressed harder than the expert on many roll-task goals and spread them ~3 cm too long (roll
            oracle 60% vs 95% with 0), while crs scored the same with either (0.963 vs 0.953, 100%).
        confine_to_goal: heuristic: the turning points stay within the goal piece's extent along the
            rolling direction (besides the piece's own ends), so dough is not spread beyond the goal:
            ``goal_inset`` radii inside the goal's ends (0.5 and 1.3 gave the same crs oracle score,
            0.942 vs 0.938 on 20 configs).
        end_tolerance: heuristic (with ``confine_to_goal``): done only when the piece's ends are within
            this of the goal's ends (or after ``max_passes``); rolling on spreads the short end.
        min_elongation: the heuristic rolls along the goal's main axis only if it is this much longer than
            wide; otherwise along x.
    """

    max_steps: int = 100
    clearance: float = 0.005
    height_min: float = 0.016
    height_max: float = 0.020
    width: float = 0.13
    length_min_factor: float = 1.15
    length_max_factor: float = 1.3
    turn_inset: float = 0.5
    length_tolerance: float = 0.005
    thickness_tolerance: float = 0.002
    min_passes: int = 2
    max_passes: int = 6
    springback: float = 0.0
    min_elongation: float = 1.3
    confine_to_goal: bool = True
    end_tolerance: float = 0.01
    goal_inset: float = 0.5


@hookimpl
def pasta_register_skills(register):
    register(spec=SPEC, factory="pasta_skill_roll.skill:RollSkill", config=RollConfig)


@hookimpl
def pasta_register_tools(register):
    register(spec=ROLLER)
