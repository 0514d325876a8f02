"""``pasta pipeline``: demonstrations, then every learned module, in one resumable run.

It sits above what it orchestrates (:mod:`pasta.demos`, :mod:`pasta.train`): one
:class:`~pasta.pipeline.stages.Stage` record per producer (:mod:`pasta.pipeline.stages`) and a generic
runner (:mod:`pasta.pipeline.run`) that plans the units, skips the done ones, resumes the interrupted ones
and records every unit's settings in ``OUT/pipeline.json``. See docs/learning.md.
"""

from pasta.pipeline.run import PipelineConfig, Unit, UnitResult, parse_arguments, plan, run_pipeline, summary_table
from pasta.pipeline.stages import STAGES, Stage

__all__ = ["STAGES", "PipelineConfig", "Stage", "Unit", "UnitResult", "parse_arguments", "plan", "run_pipeline",
           "summary_table"]
