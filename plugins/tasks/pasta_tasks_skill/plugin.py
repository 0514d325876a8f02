"""Registers the generic single-skill task ``skill`` (metadata only: the task class loads when it is built)."""

from pasta.plugins import hookimpl


@hookimpl
def pasta_register_tasks(register):
    from pasta_tasks_skill import tasks

    register(name="skill", factory="pasta_tasks_skill.tasks:SkillTask", config=tasks.SkillTaskConfig,
             summary="any registered skill alone, on its own demonstration scene (task.skill=NAME)")
