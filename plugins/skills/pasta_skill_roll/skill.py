"""The 'roll' skill: roll one dough piece flat with the roller."""

from __future__ import annotations

from pasta.core import Skill
from pasta_skill_roll.plugin import SPEC


class RollSkill(Skill):
    """roll one dough piece flat with the roller (1 -> 1 entities, tool: roller)."""

    spec = SPEC
