"""pasta's vocabulary: the contracts plugins implement and the values they exchange.

This package imports nothing else from pasta, and no heavy library at import time (torch is imported
inside the functions that need it), so listing plugins stays cheap. Shapes are named in
:mod:`pasta.core.shapes`.
"""

from pasta.core.config import PluginConfig
from pasta.core.cost import CostModel
from pasta.core.encoder import Encoder
from pasta.core.errors import (
    CardinalityError,
    ConfigError,
    InputError,
    MissingComponentError,
    PastaError,
    PluginNotFoundError,
    PluginRuntimeError,
    PluginValidationError,
    SimulationError,
)
from pasta.core.matching import min_cost_matching
from pasta.core.plan import Plan, PlanStep, kept_indices
from pasta.core.planner import Planner, PlanningProblem, check_skeleton, enumerate_skeletons, toward_goal
from pasta.core.scene import Scene, SceneNeeds
from pasta.core.skill import Controller, DemoVariant, Skill, SkillObservation, SkillSpec, ToolPose
from pasta.core.step import StepMonitor, Stop, stop_reason
from pasta.core.task import Task, TaskScore
from pasta.core.tool import ToolSpec

__all__ = [
    "CardinalityError",
    "ConfigError",
    "Controller",
    "CostModel",
    "DemoVariant",
    "Encoder",
    "InputError",
    "MissingComponentError",
    "PastaError",
    "Plan",
    "PlanStep",
    "Planner",
    "PlanningProblem",
    "PluginConfig",
    "PluginNotFoundError",
    "PluginRuntimeError",
    "PluginValidationError",
    "Scene",
    "SceneNeeds",
    "SimulationError",
    "Skill",
    "SkillObservation",
    "SkillSpec",
    "StepMonitor",
    "Stop",
    "Task",
    "TaskScore",
    "ToolPose",
    "ToolSpec",
    "check_skeleton",
    "enumerate_skeletons",
    "kept_indices",
    "min_cost_matching",
    "stop_reason",
    "toward_goal",
]
