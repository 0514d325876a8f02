"""`pasta run log=FILE` under failure (issue 21): a run that raises after its first plan step leaves FILE with
status "failed"; a killed run leaves FILE.partial with every finished step, read by `pasta replay --recover` and
re-simulated by `--verify`."""

from __future__ import annotations

import os
import signal

import pytest

from pasta.cli import main
from pasta_runs import RUN, start_run, wait_for_steps
from pasta.core.errors import SimulationError
from pasta.io import RunReader, partial_path


@pytest.mark.sim
def test_pasta_run_that_raises_after_a_step_logs_the_failure(tmp_path, monkeypatch, capsys):
    from pasta.execute.runlog import ExecutionLog

    original = ExecutionLog.step_end

    def step_end_then_fail(self, info):
        original(self, info)
        raise SimulationError(f"injected after step {info.step}")

    monkeypatch.setattr(ExecutionLog, "step_end", step_end_then_fail)
    target = tmp_path / "run.mcap"
    assert main([*RUN, f"log={target}"]) == 2
    assert "injected after step 0" in capsys.readouterr().err
    assert not partial_path(target).exists()
    r = RunReader(target)
    assert r.status == "failed" and r.error == "SimulationError: injected after step 0"
    assert r.count("/step") == 1 and r.count("/plan") == 1 and r.metadata()["seed"] == "1000"
    assert r.last("/log")[1].text == "run failed: SimulationError: injected after step 0"


@pytest.mark.sim
def test_killed_pasta_run_keeps_its_finished_steps_for_recover_and_verify(tmp_path, capsys):
    """SIGKILL after the second finished step: FILE.partial keeps both (the log is flushed at step boundaries),
    `pasta replay --recover` reads them and `--verify` re-simulates them exactly (issue 41)."""
    target = tmp_path / "run.mcap"
    partial = partial_path(target)
    proc = start_run(target)
    try:
        steps = wait_for_steps(partial, proc, 2)
        assert steps >= 2, "the run did not log two finished steps"
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert not target.exists() and partial.exists()
    r = RunReader(partial, recover=True)
    assert r.status == "truncated" and r.count("/step") >= 2 and r.count("/plan") == 1 and r.count("/actions") > 0
    assert r.metadata()["seed"] == "1000" and r.config() is not None and "initial_state.npz" in r.attachment_names()
    assert main(["replay", str(partial), "--recover"]) == 0
    out = capsys.readouterr().out
    assert "RECOVERED (truncated" in out and "step 0 cut" in out
    assert main(["replay", str(partial), "--recover", "--verify"]) == 0
    out = capsys.readouterr().out
    assert "env steps re-simulated" in out and ": OK" in out
