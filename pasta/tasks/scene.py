"""The scene a plan is for: from the task, from ``scene=``, or detected from the dough clouds.

:func:`resolve_scene` completes a declared :class:`~pasta.core.Scene` with the surface heights dough can rest on:
the floor and the top of every standing static tool that has a stand pose (``ToolSpec.stand_top``).
:func:`scene_from_setting` reads ``pasta plan``'s ``scene=`` (``auto``, ``none`` or registered static tools) and
:func:`detect_scene` is what ``auto`` does: a dough piece of the observed or the goal cloud whose bottom rests
clearly above the floor stands on something, so the scene has a surface at that height (no static tool can be
named from the dough alone: a skill that needs a named one is planned only with ``scene=NAME``).
:func:`scene_fit` says which skills a scene allows (:meth:`pasta.core.SceneNeeds.unmet`); :func:`standing_tool` is the
one lookup of a registered tool's stand pose (tasks stand their static tools with it, skills find the board).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

from pasta.core import ConfigError, Scene
from pasta.core.errors import did_you_mean

__all__ = ["AUTO", "RAISED", "detect_scene", "floor_height", "resolve_scene", "scene_fit", "scene_from_setting",
           "standing_tool"]

#: ``scene=auto``: detect the surfaces from the clouds
AUTO = "auto"
#: a piece whose bottom (2nd percentile of its heights) lies this far above the floor rests on a raised surface
#: (a piece on the floor: within 3 mm of it in the simulator; the board's top is 5 cm above it)
RAISED = 0.02


def floor_height(n_grid: int) -> float:
    """The simulator floor's height for a grid of ``n_grid`` cells (what ``Simulator.floor_y`` is)."""
    from pasta.sim.simulator import FLOOR_DX

    return FLOOR_DX / int(n_grid)


def resolve_scene(scene: Scene, floor: float, plugins: Any = None) -> Scene:
    """``scene`` with the floor and the tops of its standing static tools added to its surfaces.

    Raises:
        ConfigError: a static tool of the scene is not registered, or is not static (it has action channels).
    """
    tools = _tools(plugins)
    surfaces = [float(floor), *scene.surfaces]
    for name in scene.static:
        spec = _static_spec(name, tools)
        if spec.stand is not None:
            surfaces.append(float(spec.stand_top))
    unique = tuple(sorted({round(h, 4) for h in surfaces}))
    return Scene(static=scene.static, surfaces=unique, tools=scene.tools, source=scene.source)


def scene_from_setting(value: str, floor: float, clouds: Iterable[np.ndarray] = (), *, plugins: Any = None,
                       perception: Any = None) -> Scene:
    """``scene=``: ``auto`` (:func:`detect_scene` on ``clouds``), ``none`` (the floor alone) or comma-separated
    registered static tools (``board``), resolved."""
    text = str(value).strip()
    if text == AUTO:
        return detect_scene(clouds, floor, perception=perception)
    names = [] if text in ("", "none") else [n.strip() for n in text.split(",") if n.strip()]
    tools = _tools(plugins)
    for name in names:
        _static_spec(name, tools, setting=True)
    return resolve_scene(Scene(static=tuple(dict.fromkeys(names)), source=f"scene={text or 'none'}"), floor, plugins)


def detect_scene(clouds: Iterable[np.ndarray], floor: float, *, perception: Any = None) -> Scene:
    """Surfaces under the dough: every piece (decomposed as perception does) whose bottom lies more than
    :data:`RAISED` above ``floor`` adds a surface at its bottom's height; no static tool is named."""
    from pasta.core.decompose import decompose_labels

    if perception is None:  # the run config's decomposition settings, not a second copy of their defaults
        from pasta.config.run import PerceptionConfig

        perception = PerceptionConfig()
    eps, min_samples, min_points = float(perception.eps), int(perception.min_samples), int(perception.min_points)
    tops = []
    for cloud in clouds:
        pts = np.asarray(cloud, np.float64).reshape(-1, 3)
        if not len(pts):
            continue
        labels = decompose_labels(pts, eps=eps, min_samples=min_samples, min_points=min_points)
        for k in range(int(labels.max()) + 1):
            bottom = float(np.percentile(pts[labels == k, 1], 2))
            if bottom > floor + RAISED:
                tops.append(bottom)
    surfaces = tuple(sorted({round(float(floor), 4), *(round(h, 2) for h in tops)}))
    how = "detected from the clouds: pieces resting above the floor" if tops else "detected from the clouds: every piece on the floor"
    return Scene(surfaces=surfaces, source=f"scene=auto ({how})")


def scene_fit(names: Sequence[str], scene: Scene, skills: Any = None) -> dict[str, list[str]]:
    """Skill -> why ``scene`` does not allow it, for the skills of ``names`` it does not allow (``skills``: the
    skill registry, default the registered skills)."""
    if skills is None:
        from pasta.plugins import get_plugins

        skills = get_plugins().skills
    unmet = {}
    for name in names:
        spec = skills.info(name).spec
        reasons = spec.needs.unmet(scene, spec.tool)
        if reasons:
            unmet[name] = reasons
    return unmet


def standing_tool(name: str, plugins: Any = None) -> Any:
    """The registered :class:`~pasta.core.ToolSpec` ``name``, which must have a stand pose (``spec.stand`` (3,),
    its top ``spec.stand_top``): how a task stands its static tools and how a skill or task finds a tool another
    plugin registers (the raised board) without importing that plugin.

    Raises:
        ConfigError: no plugin registers ``name`` (with the registered tools), or it has no stand pose.
    """
    tools = _tools(plugins)
    if name not in tools:
        raise ConfigError(f"tool '{name}' is not registered{did_you_mean(name, tools.names())}; "
                          f"registered tools: {', '.join(tools.names()) or 'none'}")
    spec = tools.spec(name)
    if spec.stand is None:
        raise ConfigError(f"tool '{name}' ({tools.info(name).origin}) has no stand pose (ToolSpec.stand)")
    return spec


def _tools(plugins: Any) -> Any:
    if plugins is None:
        from pasta.plugins import get_plugins

        plugins = get_plugins()
    return plugins.tools


def _static_spec(name: str, tools: Any, *, setting: bool = False) -> Any:
    statics = [info.name for info in tools if info.spec.is_static]
    where = f"scene={name}" if setting else f"scene: static tool '{name}'"
    if name not in tools:
        raise ConfigError(f"{where}: no such registered tool{did_you_mean(name, statics)}; "
                          f"registered static tools: {', '.join(statics) or 'none'} (or scene=auto, scene=none)")
    spec = tools.info(name).spec
    if not spec.is_static:
        raise ConfigError(f"{where}: '{name}' is a movable tool, not a static one; registered static tools: "
                          f"{', '.join(statics) or 'none'}")
    return spec
