"""``task=skill``: every registered skill with a demonstration scene and an expert runs alone as a task, with no
task of its own (issue 40): its instance passes the task contract, and a bad skill or scene is named."""

import pytest

from pasta.cli import main
from pasta.demos.scene import demo_skills
from pasta.tasks import get_task
from pasta.testing import check_task


@pytest.mark.sim
@pytest.mark.parametrize("name", demo_skills())
def test_every_demo_skill_is_a_task_of_its_own(name):
    task = get_task("skill", skill=name)
    assert task.skeleton == (name,) and task.horizon == 1
    check_task(task, seed=1000)


@pytest.mark.parametrize("args, message", [
    (["task.skill=knead"], "unknown skill 'knead' for demonstrations"),
    (["task.skill=roll", "task.scene=sheets"], "skill 'roll' has no demonstration scene 'sheets'"),
])
def test_a_skill_that_cannot_run_alone_is_named_before_any_work(args, message, capsys):
    assert main(["run", "task=skill", *args, "method=oracle"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0]
