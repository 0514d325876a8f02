"""Registers the built-in CRS-family tasks (metadata only: the task classes load when a task is built)."""

from pasta.plugins import hookimpl

#: name -> (factory, config class path, summary); kept import-light (no numpy, no taichi)
_TASKS = {
    "cut": ("CutTask", "CutTaskConfig", "cut one dough box in two (1 -> 2 pieces)"),
    "push": ("PushTask", "PushTaskConfig", "push one small piece to a target centroid"),
    "roll": ("RollTask", "RollTaskConfig", "roll one small piece flat"),
    "cut_rearrange": ("CutRearrangeTask", "CutRearrangeConfig", "cut a dough box in two and move each piece to its target"),
    "crs": ("CRSTask", "CRSConfig", "cut, push the cut piece to the spreading area, roll it flat"),
    "crs_twice": ("CRSTwiceTask", "CRSTwiceConfig", "cut two pieces off a long dough, move both, flatten both (6 steps)"),
    "crs_distractors": ("CRSDistractorsTask", "CRSDistractorsConfig", "CRS with 2 extra pieces that must stay put (task.distractors=0-6)"),
}


@hookimpl
def pasta_register_tasks(register):
    from pasta_tasks_crs import tasks

    for name, (factory, config, summary) in _TASKS.items():
        register(name=name, factory=f"pasta_tasks_crs.tasks:{factory}", config=getattr(tasks, config), summary=summary)
