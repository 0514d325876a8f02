"""The 'push' skill: push one dough piece to a new place with the pusher."""

from __future__ import annotations

from pasta.core import Skill
from pasta_skill_push.plugin import SPEC


class PushSkill(Skill):
    """push one dough piece to a new place with the pusher (1 -> 1 entities, tool: pusher)."""

    spec = SPEC
