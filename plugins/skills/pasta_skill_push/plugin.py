"""Registers the 'push' skill: cardinality and tool are known here without importing torch or taichi."""

from pasta.core import SkillSpec
from pasta.plugins import hookimpl

SPEC = SkillSpec(name="push", n_in=1, n_out=1, tool="pusher", description="push one dough piece to a new place with the pusher")


@hookimpl
def pasta_register_skills(register):
    register(spec=SPEC, factory="pasta_skill_push.skill:PushSkill")
