"""Plan execution: decode sub-goals, attend the observed pieces, run each skill, score the result.

- :mod:`pasta.execute.executor`: :func:`execute_plan`, the loop, and ``execute.*`` (:class:`ExecuteConfig`);
- :mod:`pasta.execute.goals`: the controller's goal pieces of a step;
- :mod:`pasta.execute.schedule`: which step runs next, on which observed pieces;
- :mod:`pasta.execute.runlog`: the run's MCAP log;
- :mod:`pasta.execute.pipeline`: perceive -> plan -> execute one episode; :mod:`pasta.execute.session`:
  a task's models and settings for ``pasta run`` / ``pasta eval``;
- :mod:`pasta.execute.summary`: the episode's summary PNG (``pasta run summary=``).

See docs/policies.md.
"""

from pasta.execute.executor import ExecuteConfig, ExecutionResult, StepInfo, StepSnapshot, execute_plan
from pasta.execute.goals import anchor_xz, equalise_density, goal_descendants, match_goal_pieces, step_goal
from pasta.execute.schedule import attend, step_dependencies, sweep_risk

__all__ = ["ExecuteConfig", "ExecutionResult", "StepInfo", "StepSnapshot", "anchor_xz", "attend", "equalise_density", "execute_plan",
           "goal_descendants", "match_goal_pieces", "step_dependencies", "step_goal", "sweep_risk"]
