"""Registers the 'cut' skill: cardinality and tool are known here without importing torch or taichi."""

from dataclasses import dataclass

from pasta.core import SkillSpec
from pasta.plugins import hookimpl
from pasta_skill_cut.tool import KNIFE

SPEC = SkillSpec(name="cut", n_in=1, n_out=2, tool="knife", description="cut one dough piece in two with the knife")


@dataclass
class CutConfig:
    """Settings of the cut skill (distances in metres of the unit-cube workspace).

    Attributes:
        max_steps: env-step limit of one execution.
        clearance: knife tip height above the piece top at the approach pose.
        tip_depth: how far below the piece bottom the knife tip aims (the simulator stops it at its lower
            bound); with the tip that deep only the straight blade, not the wedge, meets the floor band,
            which is what cuts the bottom layer cleanly.
        offset_min, offset_max: expert sampling: cut position measured from the piece's left end;
            the upper bound is also capped at ``length - offset_min`` so both pieces keep >= offset_min.
        shift_min, shift_max: expert sampling: knife travel that pushes the left piece away after cutting.
        separate_speed: top separation speed, as a fraction of the full 0.015 per env step.
        slow_distance: the knife slows down linearly over this last distance of the separation.
        slide_allowance: the heuristic stops the knife this far before the moved part's centroid target
            (the part slides on a little).
        min_travel: heuristic: the knife separates at least this far from where it cut, even when the
            moved part already sits at its goal centroid (the descent can squeeze it there); less leaves
            the parts closer than perception's DBSCAN radius, one piece to every later step. The
            expert's smallest travel, ``shift_min``.
        fix_tolerance: heuristic: the part that stayed is pushed to its goal centroid when it is farther
            off than this.
        fix_far_side: heuristic: also fix it when that needs the knife on its far side.
        tolerance: position tolerance of the knife and centroid targets.
        grid_dx, plane_offset, plane_slope: heuristic: the measured cut model. The dough does not part
            exactly under the knife: with the knife at ``x`` it parts at
            ``x + grid_dx * (plane_offset + plane_slope * phase)``, ``phase`` = where ``x`` lies in its
            simulator grid cell (0 .. 1). Fitted on 59 recorded expert cuts (task test sets): the plane
            offset runs from +1.1 cells at phase 0 to -1.1 cells at phase 1, residual std 0.8 mm (the
            raw offset, ignoring the phase, has std 10 mm). ``grid_dx`` 0 switches the model off (the
            knife goes to the plane). Matches the default 64^3 simulator grid.
        stay_end_offset, stay_end_slope: heuristic: the cut also squeezes the part that stays (the
            knife moved the other part left): its right end moves right by
            ``stay_end_offset + stay_end_slope * phase`` (measured on the same cuts: 1.2 cm at phase 0
            to 5 cm at phase 0.9, std ~3-7 mm per phase bin). Neighbouring cells overlap, so some planes
            have two knife positions; the heuristic takes the one whose squeeze matches the goal's.
        reset_plane_sigma, reset_phase_sigma: learned reset pose (``Skill.reset_tool_x``): how far a knife's
            modelled plane (metres) and cell phase may be from the regressed ones; set before any validation
            run near the regressor's held-out errors (plane 1.6 mm; phase 0.05 of a cell, doubled).
    """

    max_steps: int = 130
    clearance: float = 0.01
    tip_depth: float = 0.075
    offset_min: float = 0.10
    offset_max: float = 0.20
    shift_min: float = 0.06
    shift_max: float = 0.08
    separate_speed: float = 0.3
    slow_distance: float = 0.02
    slide_allowance: float = 0.008
    min_travel: float = 0.06
    fix_tolerance: float = 0.006
    fix_far_side: bool = True
    tolerance: float = 0.002
    grid_dx: float = 1.0 / 64
    plane_offset: float = 1.138
    plane_slope: float = -2.269
    stay_end_offset: float = 0.012
    stay_end_slope: float = 0.043
    reset_plane_sigma: float = 0.002
    reset_phase_sigma: float = 0.1


@hookimpl
def pasta_register_skills(register):
    register(spec=SPEC, factory="pasta_skill_cut.skill:CutSkill", config=CutConfig)


@hookimpl
def pasta_register_tools(register):
    register(spec=KNIFE)
