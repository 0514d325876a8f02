"""Registers the board tasks (metadata only: the task classes load when a task is built)."""

from pasta.plugins import hookimpl

#: name -> (factory, config class, summary)
_TASKS = {
    "lift_spread": ("LiftSpreadTask", "LiftSpreadConfig",
                    "lift a dough cube onto the raised board with the spatula, roll it flat there"),
    "gather_move": ("GatherMoveTask", "GatherMoveConfig",
                    "gather three lumps into one piece with the gripper, lift it onto the board"),
}


@hookimpl
def pasta_register_tasks(register):
    from pasta_tasks_board import tasks

    for name, (factory, config, summary) in _TASKS.items():
        register(name=name, factory=f"pasta_tasks_board.tasks:{factory}", config=getattr(tasks, config), summary=summary)
