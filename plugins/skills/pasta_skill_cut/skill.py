"""The 'cut' skill: cut one dough piece in two with the knife."""

from __future__ import annotations

from pasta.core import Skill
from pasta_skill_cut.plugin import SPEC


class CutSkill(Skill):
    """cut one dough piece in two with the knife (1 -> 2 entities, tool: knife)."""

    spec = SPEC
