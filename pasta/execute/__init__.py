"""Plan execution: decode sub-goals, attend the observed pieces, run each skill, score the result.

See :func:`pasta.execute.executor.execute_plan` and docs/policies.md.
"""

from pasta.execute.executor import (
    ExecuteConfig,
    ExecutionResult,
    StepInfo,
    attend,
    decode_entities,
    equalise_density,
    execute_plan,
    match_goal_pieces,
    persisting_outputs,
)

__all__ = ["ExecuteConfig", "ExecutionResult", "StepInfo", "attend", "decode_entities", "equalise_density", "execute_plan",
           "match_goal_pieces", "persisting_outputs"]
