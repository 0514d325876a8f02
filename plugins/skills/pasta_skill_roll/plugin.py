"""Registers the 'roll' skill: cardinality and tool are known here without importing torch or taichi."""

from pasta.core import SkillSpec
from pasta.plugins import hookimpl

SPEC = SkillSpec(name="roll", n_in=1, n_out=1, tool="roller", description="roll one dough piece flat with the roller")


@hookimpl
def pasta_register_skills(register):
    register(spec=SPEC, factory="pasta_skill_roll.skill:RollSkill")
