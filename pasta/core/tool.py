"""The Tool contract: a rigid simulator tool that a skill plugin registers (geometry, actions, parking).

A :class:`ToolSpec` is plain data, known without importing taichi, so the plugin registry can list tools
and check, at load time, that every skill's ``SkillSpec.tool`` names a registered tool.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from pasta.core.errors import PluginValidationError

_NAME = re.compile(r"^[a-z][a-z0-9_]*$")


@dataclass(frozen=True)
class ToolSpec:
    """A simulator tool, registered by a plugin through ``pasta_register_tools``.

    Attributes:
        name: registry name, lower case (``"knife"``); ``SkillSpec.tool`` refers to it.
        description: one line for ``pasta plugins``.
    """

    name: str
    description: str = ""

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not _NAME.match(self.name):
            raise PluginValidationError(
                f"tool name {self.name!r} must be lower case letters, digits and '_', starting with a letter"
            )
