"""Export a demonstration (one skill episode stored as arrays) to an MCAP file for viewing."""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from pasta.io.run_log import ACTIONS, DOUGH, GOAL, TOOLS, RunLogger
from pasta.io.schemas import ACTION_SCHEMA, ToolPrimitive, step_time_ns


def _yaw_quat_wxyz(yaw: float) -> tuple[float, float, float, float]:
    """Rotation by ``yaw`` radians about the world y axis (up), scalar first."""
    return (float(np.cos(yaw / 2)), 0.0, float(np.sin(yaw / 2)), 0.0)


def _tools_at(step: int, tool_poses: Any, tool_shapes: Mapping[str, tuple[str, Sequence[float]]] | None) -> list[ToolPrimitive]:
    if isinstance(tool_poses, Mapping):
        if tool_shapes is None:
            raise ValueError("tool_shapes (name -> (kind, size)) is needed when tool_poses is a mapping")
        tools = []
        for name, poses in tool_poses.items():
            row = np.asarray(poses, dtype=np.float64)[step]
            kind, size = tool_shapes[name]
            if row.shape == (3,):
                quat = (1.0, 0.0, 0.0, 0.0)
            elif row.shape == (4,):
                quat = _yaw_quat_wxyz(row[3])
            elif row.shape == (7,):
                quat = tuple(row[3:7])
            else:
                raise ValueError(f"tool pose rows must have 3 (xyz), 4 (xyz+yaw) or 7 (xyz+quat wxyz) numbers, got {row.shape}")
            tools.append(ToolPrimitive(name, kind, size, row[:3], quat))
        return tools
    return list(tool_poses[step])


def export_demo_to_mcap(
    points_per_step: Any,
    tool_poses: Any,
    actions: Any,
    path: str | os.PathLike[str],
    *,
    dt: float = 1.0 / 60.0,
    tool_shapes: Mapping[str, tuple[str, Sequence[float]]] | None = None,
    tool_name: str = "tool",
    goal: Any = None,
    metadata: Mapping[str, Any] | None = None,
    config_yaml: str | None = None,
) -> None:
    """Write one demonstration as a run file.

    - ``points_per_step`` (T, P, 3): dough at every step -> ``/dough`` at ``t = step * dt``.
    - ``tool_poses``: None; or a length-T sequence of ``list[ToolPrimitive]``; or a mapping
      ``name -> (T, 3 | 4 | 7)`` poses (xyz, xyz + yaw about y, or xyz + quaternion wxyz) with
      ``tool_shapes[name] = (kind, size)`` -> ``/tools``.
    - ``actions``: None; a (T', A) array for the tool ``tool_name``; a mapping ``name -> (T', A)``;
      or a sequence of action dicts (``{"step", "tool", "action"}`` etc.) -> ``/actions``.
    - ``goal`` (G, 3): optional goal cloud -> ``/goal`` at t = 0.
    """
    pts = np.asarray(points_per_step)
    if pts.ndim != 3 or pts.shape[2] != 3:
        raise ValueError(f"points_per_step must have shape (T, P, 3), got {pts.shape}")
    with RunLogger(path, config_yaml=config_yaml, metadata=metadata) as log:
        if goal is not None:
            log.point_cloud(GOAL, 0, goal)
        for step in range(pts.shape[0]):
            t = step_time_ns(step, dt)
            log.point_cloud(DOUGH, t, pts[step])
            if tool_poses is not None:
                log.tools(TOOLS, t, _tools_at(step, tool_poses, tool_shapes))
        if actions is None:
            return
        if isinstance(actions, Mapping):
            per_tool = {k: np.asarray(v) for k, v in actions.items()}
            n = max((len(v) for v in per_tool.values()), default=0)
            for step in range(n):
                for name, acts in per_tool.items():
                    if step < len(acts):
                        log.action(step_time_ns(step, dt), step, name, acts[step])
        elif isinstance(actions, np.ndarray):
            for step, act in enumerate(actions):
                log.action(step_time_ns(step, dt), step, tool_name, act)
        else:
            for i, entry in enumerate(actions):
                step = int(entry.get("step", i))
                log.json(ACTIONS, step_time_ns(step, dt), entry, schema=ACTION_SCHEMA)

