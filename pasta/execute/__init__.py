"""Plan execution: decode sub-goals, attend the observed pieces, run each skill, score the result.

See :func:`pasta.execute.executor.execute_plan` and docs/policies.md.
"""

from pasta.execute.executor import (
    ExecuteConfig,
    ExecutionResult,
    StepInfo,
    anchor_xz,
    attend,
    decode_entities,
    equalise_density,
    execute_plan,
    goal_descendants,
    match_goal_pieces,
    step_goal,
)

__all__ = ["ExecuteConfig", "ExecutionResult", "StepInfo", "anchor_xz", "attend", "decode_entities", "equalise_density",
           "execute_plan", "goal_descendants", "match_goal_pieces", "step_goal"]
