"""Tasks in the simulator: a generated instance is reproducible and the oracle solves it."""

from __future__ import annotations

import numpy as np
import pytest

from pasta.tasks import TaskInstance, get_task
from pasta.tasks.oracle import attended_piece, run_oracle

pytestmark = pytest.mark.sim


@pytest.fixture(scope="module")
def push_task():
    return get_task("push", n_particles=2000)


@pytest.fixture(scope="module")
def sim(push_task):
    return push_task.make_sim()


def test_generation_is_reproducible_and_cached(push_task, sim, tmp_path, monkeypatch):
    monkeypatch.setenv("PASTA_TASK_CACHE", str(tmp_path))
    first = push_task.instance(1000, sim=sim)
    path = push_task.cache_path(1000)
    assert path.exists() and str(path).startswith(str(tmp_path))
    again = push_task.generate(1000, sim=sim)
    a, b = first.to_arrays(), again.to_arrays()
    assert a.keys() == b.keys()
    for k in a:
        np.testing.assert_array_equal(a[k], b[k], err_msg=k)
    assert again.save(tmp_path / "again.npz").read_bytes() == path.read_bytes()
    loaded = push_task.instance(1000)  # from the cache, no simulator needed
    assert isinstance(loaded, TaskInstance) and loaded.skeleton == ["push"]
    step = loaded.steps[0]
    target = np.array([step.params["target_x"], step.params["target_z"]])
    assert np.linalg.norm(loaded.step_goal(0)[:, [0, 2]].mean(0) - target) < 0.02  # the expert reached its target


def test_oracle_solves_a_push_instance(push_task, sim, tmp_path, monkeypatch):
    monkeypatch.setenv("PASTA_TASK_CACHE", str(tmp_path))
    inst = push_task.instance(1001, sim=sim)
    res = run_oracle(push_task, inst, sim)
    assert res.score.emd_initial > 0.1
    assert res.score.success and res.score.improvement > 0.85
    # the initial state scores 0
    assert push_task.score(inst.init_points, inst).improvement == 0.0


def test_attended_piece_by_particle_overlap():
    rng = np.random.default_rng(0)
    a = rng.random((100, 3)) * 0.05 + [0.3, 0.02, 0.5]
    b = rng.random((60, 3)) * 0.05 + [0.6, 0.02, 0.5]
    dough = np.concatenate([a, b])
    np.testing.assert_array_equal(attended_piece(dough, np.arange(100, 130)), np.arange(100, 160))
