"""`pasta run log=FILE` under failure (issue 21): a run that raises after its first plan step leaves FILE with
status "failed"; a killed run leaves FILE.partial with every finished step, read by `pasta replay --recover`."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pytest

from pasta.cli import main
from pasta.core.errors import SimulationError
from pasta.io import RunReader, partial_path

# shipped weights, heuristic controllers, a short optimisation: ~10 s of CPU
RUN = ["run", "task=crs", "seed=1000", "planner.iterations=10", "execute.idle_steps=2", "execute.retries=0"]


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
def test_killed_pasta_run_leaves_a_partial_file_with_its_finished_steps(tmp_path, capsys):
    target = tmp_path / "run.mcap"
    partial = partial_path(target)
    proc = subprocess.Popen([sys.executable, "-m", "pasta", *RUN, f"log={target}"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 180
        steps = 0
        while steps < 1 and time.monotonic() < deadline and proc.poll() is None:
            time.sleep(0.5)
            if partial.exists():  # read while it is written: recover keeps what is complete so far
                steps = RunReader(partial, recover=True).count("/step")
        assert steps >= 1, "the run did not log a finished step"
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert not target.exists() and partial.exists()
    r = RunReader(partial, recover=True)
    assert r.status == "truncated" and r.count("/step") >= 1 and r.count("/plan") == 1
    assert r.metadata()["seed"] == "1000" and r.config() is not None and "initial_state.npz" in r.attachment_names()
    assert main(["replay", str(partial), "--recover"]) == 0
    out = capsys.readouterr().out
    assert "RECOVERED (truncated" in out and "step 0 cut" in out
