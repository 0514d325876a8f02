"""``pasta.distributed.map_jobs`` without Ray: in this process and in local worker processes; the backend
arguments and their one-line errors (no Ray needed; the Ray side is test_ray.py).

The jobs are the toys of ``_distributed_jobs`` (no simulator).
"""

from __future__ import annotations

import sys

import _distributed_jobs as toy
import pytest

from pasta.core.errors import ConfigError
from pasta.distributed import TEST_KILL_ENV, TEST_STOP_ENV, BackendConfig, BackendError, split_backend_args

RAY = BackendConfig(name="ray")


def test_in_process_values_and_a_failing_item():
    out = toy.run(BackendConfig(), 0)
    toy.check_values(out)
    assert {o.value["attempt"] for o in out.values() if o.ok} == {1}


def test_local_workers_values_and_a_failing_item():
    out = toy.run(BackendConfig(), 2)
    toy.check_values(out)
    assert len({o.value["pid"] for o in out.values() if o.ok}) <= 2  # state built once per worker process


def test_local_worker_killed_once_is_retried(monkeypatch, capfd):
    monkeypatch.setenv(TEST_KILL_ENV, "1@1")
    out = toy.run(BackendConfig(), 2)
    toy.check_values(out)
    assert out[1].attempts == 2 and out[1].value["attempt"] == 2
    assert "killed by SIGKILL on toy 1; toy 1 goes back to the queue" in capfd.readouterr().err


def test_local_worker_stopped_once_passes_its_deadline_and_is_retried(monkeypatch, capfd):
    monkeypatch.setenv(TEST_STOP_ENV, "1@1")  # the worker on item 1 stops (SIGSTOP) on its first attempt only
    with toy.hang_guard():
        out = toy.run(BackendConfig(), 2, deadline_s=3)
    toy.check_values(out)
    assert out[1].attempts == 2 and out[1].value["attempt"] == 2
    assert "on toy 1 exceeded the deadline of 3 s and was killed; toy 1 goes back to the queue" in capfd.readouterr().err


def test_local_item_that_always_hangs_is_reported_after_2_attempts_others_complete(monkeypatch):
    monkeypatch.setenv(TEST_STOP_ENV, "1")  # every worker that starts item 1 stops
    with toy.hang_guard():
        out = toy.run(BackendConfig(), 2, deadline_s=2.5)
    assert not out[1].ok and out[1].attempts == 2
    assert out[1].error == "it exceeded its deadline of 2.5 s on each of 2 attempts (deadline_s= sets the deadline)"
    assert all(out[i].ok for i in (0, 2, 4)) and not out[3].ok and out[3].attempts == 1


def test_local_workers_that_hang_while_starting_are_killed_then_the_run_stops(monkeypatch, capfd):
    monkeypatch.setattr("pasta.distributed.local.STARTUP_S", 2.0)  # the start-up limit: max(STARTUP_S, deadline_s)
    with toy.hang_guard(), pytest.raises(BackendError, match="the last one did not start within 2 s and was killed"):
        toy.run(BackendConfig(), 2, setup={"scale": 1, "stop_init": True}, deadline_s=1)
    assert "did not start within 2 s and was killed; a new one starts" in capfd.readouterr().err


def test_split_backend_args():
    cfg, rest = split_backend_args(["skill=push", "backend=ray", "ray.address=auto", "ray.num_cpus=2", "num=3"])
    assert (cfg.name, cfg.address, cfg.num_cpus) == ("ray", "auto", 2) and rest == ["skill=push", "num=3"]
    cfg, rest = split_backend_args({"data": "x", "workers": 0})
    assert cfg.name == "local" and rest == {"data": "x", "workers": 0} and cfg.deadline_s == 0
    cfg, rest = split_backend_args(["deadline_s=90", "num=3"])
    assert cfg.deadline_s == 90.0 and rest == ["num=3"]
    for bad, msg in [(["backend=rya"], "backend=rya: must be one of local, ray; did you mean 'ray'"),
                     (["ray.adress=auto", "backend=ray"], "unknown key 'ray.adress'"),
                     (["ray.address=auto"], "ray.address is a setting of the Ray backend; add backend=ray"),
                     (["backend=ray", "ray.num_cpus=-1"], "ray.num_cpus=-1"),
                     (["deadline_s=-1"], "deadline_s=-1: must be a finite number >= 0 (seconds an item may run"),
                     (["deadline_s=soon"], "deadline_s=soon: must be a finite number >= 0")]:
        with pytest.raises(ConfigError, match=msg.replace("(", r"\(").replace(")", r"\)")):
            split_backend_args(bad)


def test_missing_ray_is_a_one_line_error(monkeypatch, capsys, tmp_path):
    from pasta.cli import main

    monkeypatch.setitem(sys.modules, "ray", None)  # import ray -> ImportError
    with pytest.raises(ConfigError, match=r"backend=ray needs Ray, which is not installed: pip install pasta-dough\[ray\]"):
        toy.run(RAY, 2)
    assert main(["demos", "skill=push", "num=1", f"out={tmp_path}", "backend=ray"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].endswith("backend=ray needs Ray, which is not installed: pip install pasta-dough[ray]")


@pytest.mark.parametrize("args", [["demos", "skill=push", "backend=rya"], ["eval", "task=push", "ray.address=auto"],
                                  ["pipeline", "backend=slurm"]])
def test_cli_bad_backend_exits_2(args, capsys, tmp_path):
    from pasta.cli import main

    assert main(args + [f"out={tmp_path}"]) == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1


@pytest.mark.parametrize("args", [["demos", "skill=push", "deadline_s=-1"], ["eval", "task=push", "deadline_s=soon"],
                                  ["pipeline", "deadline_s=-3"]])
def test_cli_bad_deadline_exits_2_naming_the_key(args, capsys, tmp_path):
    from pasta.cli import main

    assert main(args + [f"out={tmp_path}"]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert f"{args[-1]}: must be a finite number >= 0 (seconds an item may run in a worker" in line


def test_init_failure_stops_the_run():
    with pytest.raises(BackendError, match="a worker could not start"):
        toy.run(BackendConfig(), 2, setup={"scale": 1, "fail_init": True})


def test_unreachable_ray_address_fails_fast(capsys, tmp_path):
    """Nothing listens at the address: one error line naming it, exit 1, no demo made (ray.init would retry
    for minutes)."""
    import socket

    from pasta.cli import main

    ray = toy.require_ray()
    if ray.is_initialized():
        pytest.skip("a Ray instance is running in this process")
    with socket.socket() as s:  # a port nothing listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    assert main(["demos", "skill=push", "num=1", f"out={tmp_path}", "backend=ray", f"ray.address=127.0.0.1:{port}"]) == 1
    err = capsys.readouterr().err
    assert f"could not reach ray.address=127.0.0.1:{port}" in err and "ray start --head" in err
    assert not list((tmp_path / "push").glob("*.npz"))


def test_local_backend_never_imports_ray():
    import subprocess

    code = ("import sys, pasta.distributed as d, pasta.commands.eval, pasta.demos.generate, pasta.pipeline; "
            "cfg, rest = d.split_backend_args(['backend=local', 'num=2']); "
            "out = list(d.map_jobs(len, lambda s, i, a: i * s, [1, 2], [0, 1], backend=cfg.check())); "
            "assert [o.value for o in out] == [0, 2], out; print('ray' in sys.modules)")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "False"
