"""Registers the 'cut' skill: cardinality and tool are known here without importing torch or taichi."""

from pasta.core import SkillSpec
from pasta.plugins import hookimpl

SPEC = SkillSpec(name="cut", n_in=1, n_out=2, tool="knife", description="cut one dough piece in two with the knife")


@hookimpl
def pasta_register_skills(register):
    register(spec=SPEC, factory="pasta_skill_cut.skill:CutSkill")
