"""Run logging: one MCAP file per run (point clouds, tools, plans, actions, metrics, logs,
config, metadata, attachments), readable in Foxglove / Lichtblick and by :class:`RunReader`.

This package is the only place in pasta that imports ``mcap``. See ``docs/logging.md``.
"""

from pasta.io.errors import McapFormatError, McapTruncatedError
from pasta.io.run_log import (
    ACTIONS,
    CONFIG_ATTACHMENT,
    DOUGH,
    ENTITIES,
    FINAL_STATE,
    GOAL,
    INITIAL_STATE,
    LOG,
    METRICS,
    PLAN,
    PROGRESS,
    RUN_STATUS,
    SIM_CONFIG,
    STEP,
    SUBGOALS,
    TOOLS,
    RunLogger,
    partial_path,
)
from pasta.io.run_reader import LoggedMessage, RunReader, TopicInfo
from pasta.io.schemas import LogEntry, ToolPrimitive, step_time_ns
from pasta.io.demo_export import export_demo_to_mcap

__all__ = [
    "ACTIONS",
    "CONFIG_ATTACHMENT",
    "DOUGH",
    "ENTITIES",
    "FINAL_STATE",
    "GOAL",
    "INITIAL_STATE",
    "LOG",
    "METRICS",
    "PLAN",
    "PROGRESS",
    "RUN_STATUS",
    "SIM_CONFIG",
    "STEP",
    "SUBGOALS",
    "TOOLS",
    "LogEntry",
    "LoggedMessage",
    "McapFormatError",
    "McapTruncatedError",
    "RunLogger",
    "RunReader",
    "ToolPrimitive",
    "TopicInfo",
    "export_demo_to_mcap",
    "partial_path",
    "step_time_ns",
]
