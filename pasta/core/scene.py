"""What a scene offers and what a skill needs from it: the planner only considers skills the scene allows.

A skill declares its needs in its :class:`~pasta.core.SkillSpec` (``needs=SceneNeeds(...)``): static tools that must
stand in the scene (by registry name), and a surface to set dough down on whose top lies in a height range (a
raised board, a shelf: any standing static tool, or a surface the scene names). A skill always needs its own tool.

A task declares its scene (:meth:`pasta.core.Task.scene`: the static tools its instances stand up); ``pasta plan``
takes one from ``scene=`` or detects it from the clouds. :mod:`pasta.tasks.scene` adds the surface heights (the
floor, the tops of the standing tools) and fits the skills to it. Both are plain data, known before any network
or simulator exists.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

__all__ = ["Scene", "SceneNeeds"]


def _names(value: Any, what: str) -> tuple[str, ...]:
    from pasta.core.errors import PluginValidationError

    if not isinstance(value, (tuple, list)) or not all(isinstance(v, str) and v for v in value):
        raise PluginValidationError(f"{what} must be a tuple of tool names, got {value!r}")
    return tuple(value)


@dataclass(frozen=True)
class Scene:
    """The workspace a plan is for.

    Attributes:
        static: static tools standing in the scene (registry names, e.g. ``("board",)``).
        surfaces: heights y (metres) of the tops dough can rest on besides those of the floor and the standing
            static tools, which :func:`pasta.tasks.scene.resolve_scene` adds.
        tools: the movable tools at hand; ``None``: every registered tool.
        source: how the scene was obtained, for messages (``"task cut_rearrange"``, ``"scene=board"``).
    """

    static: tuple[str, ...] = ()
    surfaces: tuple[float, ...] = ()
    tools: tuple[str, ...] | None = None
    source: str = ""

    def describe(self) -> str:
        """One line: ``task lift_spread: static board; surfaces at 2.0, 7.0 cm``."""
        parts = [f"static {', '.join(self.static)}" if self.static else "no static tools"]
        if self.surfaces:
            parts.append("surfaces at " + ", ".join(f"{100 * h:.1f}" for h in sorted(self.surfaces)) + " cm")
        if self.tools is not None:
            parts.append(f"tools {', '.join(self.tools) or 'none'}")
        return f"{self.source + ': ' if self.source else ''}{'; '.join(parts)}"


@dataclass(frozen=True)
class SceneNeeds:
    """What a skill needs from the scene besides its own tool.

    Attributes:
        static: static tools that must stand in the scene.
        surface: ``(low, high)``: a surface whose top lies at a height within it (metres; the floor counts);
            ``None``: any.
        why: a few words for messages (``"a raised surface to set the dough down on"``).
    """

    static: tuple[str, ...] = ()
    surface: tuple[float, float] | None = None
    why: str = ""

    def __post_init__(self) -> None:
        from pasta.core.errors import PluginValidationError

        object.__setattr__(self, "static", _names(self.static, "SceneNeeds.static"))
        if self.surface is not None:
            low, high = (float(v) for v in self.surface)
            if not low <= high:
                raise PluginValidationError(f"SceneNeeds.surface must be (low, high) with low <= high, got {self.surface!r}")
            object.__setattr__(self, "surface", (low, high))

    def describe(self) -> str:
        """What is needed, in words (empty when nothing is)."""
        parts = [f"static tool{'s' if len(self.static) > 1 else ''} {', '.join(self.static)}"] if self.static else []
        if self.surface is not None:
            parts.append(f"{self.why or 'a surface'} {100 * self.surface[0]:.0f}-{100 * self.surface[1]:.0f} cm high")
        elif self.why and parts:
            parts[-1] += f" ({self.why})"
        return "; ".join(parts)

    def unmet(self, scene: Scene, tool: str | None = None) -> list[str]:
        """Why ``scene`` does not allow a skill with these needs driving ``tool`` (empty: it does)."""
        reasons = []
        if tool is not None and scene.tools is not None and tool not in scene.tools:
            reasons.append(f"its tool '{tool}' is not in the scene")
        missing = [name for name in self.static if name not in scene.static]
        if missing:
            reasons.append(f"needs the static tool{'s' if len(missing) > 1 else ''} {', '.join(missing)}"
                           + (f" ({self.why})" if self.why else ""))
        if self.surface is not None:
            low, high = self.surface
            if not any(low <= h <= high for h in scene.surfaces):
                have = ", ".join(f"{100 * h:.1f}" for h in sorted(scene.surfaces)) or "none"
                reasons.append(f"needs {self.why or 'a surface'} {100 * low:.0f}-{100 * high:.0f} cm high, "
                               f"and the scene's surfaces are at {have} cm")
        return reasons
