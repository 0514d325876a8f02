"""Crash-safe run logs (issue 21): written as FILE.partial and renamed on close; a failed run records its
error; a killed run leaves a .partial file that ``--recover`` reads; an existing FILE is kept until success."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from pasta.cli import main
from pasta.io import McapFormatError, McapTruncatedError, RunLogger, RunReader
from pasta.io.run_log import partial_path


def _steps(log, n, start=0):
    for i in range(start, start + n):
        log.point_cloud("/dough", i * 1000, np.full((50, 3), i, np.float32))
        log.step_result(i * 1000, {"step": i, "skill": "cut", "score": 0.1 * i})


def test_existing_target_is_kept_until_the_run_closes(tmp_path):
    target = tmp_path / "run.mcap"
    target.write_bytes(b"the previous run")
    log = RunLogger(target, metadata={"seed": 1})
    _steps(log, 3)
    log.flush()
    assert log.partial_path == tmp_path / "run.mcap.partial" and log.partial_path.stat().st_size > 0
    assert target.read_bytes() == b"the previous run"  # not truncated at start
    log.close()
    assert not log.partial_path.exists()
    r = RunReader(target)
    assert r.status == "complete" and r.error is None and r.count("/dough") == 3


def test_a_run_that_raises_records_the_failure(tmp_path, capsys):
    target = tmp_path / "run.mcap"
    target.write_bytes(b"the previous run")
    with pytest.raises(RuntimeError, match="boom"):
        with RunLogger(target, metadata={"seed": 1}) as log:
            _steps(log, 4)
            raise RuntimeError("boom after 4 steps")
    assert not partial_path(target).exists()
    r = RunReader(target)  # a finished, indexed file: no --recover needed
    assert r.status == "failed" and r.error == "RuntimeError: boom after 4 steps"
    assert r.count("/dough") == 4 and r.metadata() == {"seed": "1"}
    t, entry = r.last("/log")
    assert t == 3000 and entry.level == "error" and entry.text == "run failed: RuntimeError: boom after 4 steps"

    assert main(["replay", str(target)]) == 0
    cap = capsys.readouterr()
    assert "(FAILED: RuntimeError: boom after 4 steps)" in cap.out and "run failed: RuntimeError" in cap.out
    assert "warning: the logged run failed: RuntimeError: boom after 4 steps" in cap.err


def test_status_record_is_reserved_and_a_directory_target_is_refused_at_start(tmp_path):
    with RunLogger(tmp_path / "a.mcap") as log:
        with pytest.raises(ValueError, match="'status' is written by close"):
            log.add_metadata("status", {"status": "complete"})
    with pytest.raises(IsADirectoryError, match="directory"):
        RunLogger(tmp_path)
    assert not list(tmp_path.glob("*.partial"))


_WRITER = textwrap.dedent("""
    import sys, time
    import numpy as np
    from pasta.io import RunLogger
    log = RunLogger(sys.argv[1], config_yaml="seed: 7\\n", metadata={"seed": 7}, chunk_size=4096)
    for i in range(30):
        log.point_cloud("/dough", i * 1000, np.full((100, 3), i, np.float32))
        if i % 10 == 9:
            log.flush()  # what the executor does after every plan step
    print("flushed", flush=True)
    log.point_cloud("/dough", 31000, np.zeros((10, 3), np.float32))  # in the open chunk: lost
    time.sleep(60)
""")


@pytest.mark.parametrize("previous", [None, b"the previous run"])
def test_a_killed_run_leaves_a_partial_file_that_recover_reads(tmp_path, capsys, previous):
    target = tmp_path / "run.mcap"
    if previous is not None:
        target.write_bytes(previous)
    proc = subprocess.Popen([sys.executable, "-c", _WRITER, str(target)], stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline().strip() == "flushed"
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.stdout.close()
    partial = partial_path(target)
    assert partial.exists()
    if previous is None:
        assert not target.exists()
        with pytest.raises(McapFormatError, match=r"run\.mcap\.partial exists: the run was killed.*--recover"):
            RunReader(target)
    else:
        assert target.read_bytes() == previous
    with pytest.raises(McapTruncatedError, match="--recover"):
        RunReader(partial)
    r = RunReader(partial, recover=True)
    assert r.status == "truncated" and r.error is None
    assert [t for t, _ in r.messages("/dough")] == [i * 1000 for i in range(30)]  # every flushed chunk
    assert r.metadata() == {"seed": "7"} and r.config() == "seed: 7\n"

    assert main(["replay", str(partial), "--recover"]) == 0
    cap = capsys.readouterr()
    assert "RECOVERED (truncated" in cap.out and "recovered 31 messages" in cap.err  # 30 clouds and the /tf transform
