"""The Ray backend on a local Ray instance with 2 CPUs (``ray_local``, one per module: every Ray test is here).

- ``map_jobs`` with toy jobs: values, a job's exception reported with its item, a killed worker retried
  or reported after 2 attempts while the others complete, a stopped (SIGSTOP) worker's task cancelled at
  its deadline and retried or reported after 2 attempts, a worker that hangs while starting given up,
  a failing ``init`` stopping the run.
- The same seed gives the same results under ``backend=local`` and ``backend=ray`` (issue 19): demo
  files compared byte for byte (also after a Ray worker is killed mid-demo and after a resumed run), eval
  rows compared field by field less the wall times and the provenance (which name the process that ran them).
"""

from __future__ import annotations

import json
import os

import _distributed_jobs as toy
import pytest

from pasta.cli import main
from pasta.demos import DemoConfig, generate_demos
from pasta.distributed import TEST_KILL_ENV, TEST_STOP_ENV, BackendConfig, BackendError

TINY = dict(skill="push", n_particles=1000, obs_points=200, settle_steps=2, idle_steps=2, seed=3)
RAY = BackendConfig(name="ray")
#: fields of an eval row that legitimately differ between two runs of the same episode
TIMING = {"wall_s", "plan_s", "execute_s", "provenance"}


def test_ray_values_and_a_failing_item(ray_local):
    out = toy.run(RAY, 2)
    toy.check_values(out)
    pids = {o.value["pid"] for o in out.values() if o.ok}
    assert os.getpid() not in pids  # they ran in Ray workers, not here


def test_ray_worker_killed_once_is_retried(ray_local, monkeypatch, capfd):
    monkeypatch.setenv(TEST_KILL_ENV, "2@1")  # the worker that starts item 2 dies on its first attempt
    out = toy.run(RAY, 2)
    toy.check_values(out)
    assert out[2].attempts == 2 and out[2].value["attempt"] == 2
    assert "Ray worker died (WorkerCrashedError) on toy 2; toy 2 goes back to the queue" in capfd.readouterr().err


def test_ray_item_that_always_kills_its_worker_is_reported_others_complete(ray_local, monkeypatch):
    monkeypatch.setenv(TEST_KILL_ENV, "2")
    out = toy.run(RAY, 0)  # 0: as many in flight as the cluster has CPUs
    assert not out[2].ok and out[2].attempts == 2
    assert out[2].error == "its Ray worker died (WorkerCrashedError) on each of 2 attempts"
    assert all(out[i].ok for i in (0, 1, 4)) and not out[3].ok


def test_ray_worker_stopped_once_passes_its_deadline_and_is_retried(ray_local, monkeypatch, capfd):
    monkeypatch.setenv(TEST_STOP_ENV, "2@1")  # the worker on item 2 stops (SIGSTOP) on its first attempt only
    with toy.hang_guard():
        out = toy.run(RAY, 2, deadline_s=3)
    toy.check_values(out)
    assert out[2].attempts == 2 and out[2].value["attempt"] == 2
    assert ("the Ray task of toy 2 exceeded the deadline of 3 s and was cancelled; toy 2 goes back to the queue"
            in capfd.readouterr().err)


def test_ray_item_that_always_hangs_is_reported_after_2_attempts_others_complete(ray_local, monkeypatch):
    monkeypatch.setenv(TEST_STOP_ENV, "2")
    with toy.hang_guard():
        out = toy.run(RAY, 0, deadline_s=2.5)
    assert not out[2].ok and out[2].attempts == 2
    assert out[2].error == "it exceeded its deadline of 2.5 s on each of 2 attempts (deadline_s= sets the deadline)"
    assert all(out[i].ok for i in (0, 1, 4)) and not out[3].ok


def test_ray_worker_that_hangs_while_starting_is_cancelled_and_its_items_reported(ray_local, monkeypatch):
    monkeypatch.setattr("pasta.distributed.ray_backend.STARTUP_S", 2.0)  # the limit from the task's begin to ready
    with toy.hang_guard():
        out = toy.run(RAY, 2, items=(0, 1), setup={"scale": 1, "stop_init": True}, deadline_s=1)
    for i in (0, 1):
        assert not out[i].ok and out[i].attempts == 2
        assert out[i].error == "its Ray worker did not start within 2 s on each of 2 attempts"


def test_init_failure_stops_the_run(ray_local):
    with pytest.raises(BackendError, match="could not start"):
        toy.run(RAY, 2, setup={"scale": 1, "fail_init": True})


def _files(folder):
    return {p.name: p.read_bytes() for p in sorted(folder.glob("*"))}


@pytest.mark.sim
def test_demos_same_bytes_local_and_ray_with_a_killed_worker_and_a_resume(ray_local, tmp_path, monkeypatch, capfd):
    generate_demos(DemoConfig(num=3, out=str(tmp_path / "local"), workers=0, **TINY), progress=False)
    monkeypatch.setenv(TEST_KILL_ENV, "1@1")  # the Ray worker that starts demo 1 dies on its first attempt
    cfg = DemoConfig(num=3, out=str(tmp_path / "ray"), workers=2, **TINY)
    summary = generate_demos(cfg, progress=False, backend=RAY)
    assert summary["generated"] == 3 and summary["backend"] == "ray (local instance)"
    assert "Ray worker died (WorkerCrashedError) on demo 1; demo 1 goes back to the queue" in capfd.readouterr().err
    local, ray = _files(tmp_path / "local" / "push"), _files(tmp_path / "ray" / "push")
    assert list(ray) == [f"demo_0000{i}.npz" for i in range(3)]  # and nothing else (no temporary files)
    assert ray == local
    monkeypatch.delenv(TEST_KILL_ENV)
    (tmp_path / "ray" / "push" / "demo_00002.npz").unlink()  # as if the driver had been killed before writing it
    summary = generate_demos(cfg, progress=False, backend=RAY)
    assert (summary["generated"], summary["skipped"]) == (1, 2)
    assert _files(tmp_path / "ray" / "push") == local


def _rows(path):
    rows = {}
    for line in path.read_text().splitlines():
        row = json.loads(line)
        row = {k: v for k, v in row.items() if k not in TIMING}
        row["steps"] = [{k: v for k, v in s.items() if k != "wall_s"} for s in row.get("steps", [])]
        rows[row["seed"]] = row
    return rows


@pytest.mark.sim
def test_eval_rows_same_local_and_ray(ray_local, tmp_path, monkeypatch, capfd):
    # a short planner and episode: the rows are what is compared, not how good they are
    args = ["eval", "task=push", "method=pasta", "num=2", "planner.num_samples=32", "planner.iterations=20",
            "skill.push.max_steps=25"]
    assert main(args + [f"out={tmp_path / 'local'}"]) == 0
    monkeypatch.setenv(TEST_KILL_ENV, "1001@1")  # the Ray worker on episode 1001 dies once: it is rerun
    assert main(args + [f"out={tmp_path / 'ray'}", "backend=ray", "workers=2"]) == 0
    err = capfd.readouterr().err
    assert "Ray worker died (WorkerCrashedError) on episode 1001; episode 1001 goes back to the queue" in err
    assert "on ray (local instance) with 2 workers" in err
    # the file is named after the settings (push_pasta_<setting>...): the same name in both folders
    (name,) = [p.stem for p in (tmp_path / "local").glob("push_pasta*.jsonl")]
    local, ray = _rows(tmp_path / "local" / f"{name}.jsonl"), _rows(tmp_path / "ray" / f"{name}.jsonl")
    assert sorted(local) == sorted(ray) == [1000, 1001]
    for seed in local:
        assert ray[seed] == local[seed]
    a = json.loads((tmp_path / "local" / f"{name}.json").read_text())
    b = json.loads((tmp_path / "ray" / f"{name}.json").read_text())
    assert (a["improvement_mean"], a["success_rate"]) == (b["improvement_mean"], b["success_rate"])


@pytest.mark.sim
def test_pipeline_demos_units_on_ray_then_skipped_under_local(ray_local, tmp_path):
    from pasta.pipeline import run_pipeline

    tiny = [f"demos.{k}={v}" for k, v in TINY.items() if k != "skill"]
    args = [f"data={tmp_path / 'demos'}", f"out={tmp_path / 'models'}", "stages=demos", "skills=push",
            "num_demos=2", "variant_demos=0", "workers=2", *tiny]
    lines: list[str] = []
    results = run_pipeline([*args, "backend=ray"], echo=lines.append)
    assert [(r.name, r.status) for r in results] == [("demos/push", "ran")]
    assert "backend=ray (local instance)" in lines[0]
    reference = tmp_path / "reference"
    generate_demos(DemoConfig(num=2, out=str(reference), workers=0, **TINY), progress=False)
    assert _files(tmp_path / "demos" / "push") == _files(reference / "push")
    # the backend is not a setting of the unit: under local it is done already
    results = run_pipeline([*args, "backend=local"], echo=lines.append)
    assert [(r.name, r.status) for r in results] == [("demos/push", "skipped")]
