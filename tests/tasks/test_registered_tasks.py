"""Every registered task passes the task contract: one instance each (seed 1000, the first fixed test config,
with the task's default settings), generated once into the task cache and read from it afterwards
(first generation on a 2-core machine: 2-10 s per task, crs_twice 30 s)."""

import pytest

from pasta.plugins import get_plugins
from pasta.tasks import get_task
from pasta.testing import check_task

pytestmark = pytest.mark.sim


@pytest.mark.parametrize("name", get_plugins().tasks.names())
def test_registered_task_conforms(name):
    check_task(get_task(name), seed=1000)
