"""Worker processes of ``pasta demos`` (issue 21): a killed worker's demo is re-queued or reported with its seed,
the run exits non-zero when it cannot finish, and killing the parent stops its workers.

Workers kill themselves through the test hook ``PASTA_DEMOS_TEST_KILL`` (read in the spawned workers).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from pasta.cli import main
from pasta.demos import DemoConfig, generate_demos
from pasta.demos.workers import TEST_KILL_ENV

TINY = dict(skill="push", n_particles=1000, obs_points=200, settle_steps=2, idle_steps=2, seed=3)


@pytest.mark.sim
def test_killed_worker_demo_is_requeued(tmp_path, monkeypatch, capfd):
    monkeypatch.setenv(TEST_KILL_ENV, "1@1")  # the worker on demo 1 dies on its first attempt only
    t0 = time.monotonic()
    summary = generate_demos(DemoConfig(num=3, out=str(tmp_path), workers=2, **TINY), progress=False)
    assert summary["generated"] == 3 and time.monotonic() - t0 < 240
    assert "killed by SIGKILL on demo 1; demo 1 goes back to the queue" in capfd.readouterr().err
    folder = tmp_path / "push"
    assert sorted(p.name for p in folder.iterdir()) == [f"demo_0000{i}.npz" for i in range(3)]  # no .tmp left
    with np.load(folder / "demo_00001.npz", allow_pickle=False) as z:
        assert z["dough"].shape[1:] == (200, 3) and str(z["skill"]) == "push"


@pytest.mark.sim
def test_demo_that_always_kills_its_worker_is_reported_and_exit_is_nonzero(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv(TEST_KILL_ENV, "1")  # every attempt of demo 1 dies
    args = ["demos", f"out={tmp_path}", "num=3", "workers=1"] + [f"{k}={v}" for k, v in TINY.items()]
    t0 = time.monotonic()
    assert main(args) == 1
    assert time.monotonic() - t0 < 240
    err = capsys.readouterr().err
    assert "1 of 3 demos of push could not be made" in err
    assert "demo 1 (seed=3 skill=push index=1): its worker was killed by SIGKILL on each of 2 attempts" in err
    assert sorted(p.name for p in (tmp_path / "push").iterdir()) == ["demo_00000.npz", "demo_00002.npz"]


def test_demo_deadline_is_derived_from_the_skill_or_given(tmp_path, monkeypatch):
    """The deadline handed to the workers: 0 derives it from the skill's step limit and the particles."""
    import pasta.distributed
    from pasta.demos.generate import demo_deadline
    from pasta.distributed import STARTUP_S, BackendConfig

    seen = []
    monkeypatch.setattr(pasta.distributed, "map_jobs", lambda *a, **k: seen.append(k["deadline_s"]) or iter(()))
    cfg = DemoConfig(skill="push", num=2, out=str(tmp_path), workers=2)
    generate_demos(cfg, progress=False)
    generate_demos(cfg, progress=False, backend=BackendConfig(deadline_s=42))
    assert seen == [demo_deadline(cfg), 42.0]
    # push: 10 settle + max_steps 80 + 10 idle steps at 1 s each, after the start-up allowance
    assert demo_deadline(cfg) == STARTUP_S + 100
    assert demo_deadline(DemoConfig(skill="lift")) == STARTUP_S + 180
    assert demo_deadline(DemoConfig(skill="push", n_particles=10000)) == STARTUP_S + 200


def _children(pid: int) -> list[int]:
    """Live (not zombie) processes whose parent is ``pid`` (Linux /proc)."""
    out = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue
        state, ppid = stat.rsplit(")", 1)[1].split()[:2]
        if int(ppid) == pid and state != "Z":
            out.append(int(entry.name))
    return out


def _alive(pid: int) -> bool:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


@pytest.mark.sim
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_killing_the_parent_stops_its_workers(tmp_path):
    args = [sys.executable, "-m", "pasta", "demos", f"out={tmp_path}", "num=50", "workers=2"]
    args += [f"{k}={v}" for k, v in TINY.items()]
    parent = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    workers: list[int] = []
    try:
        deadline = time.monotonic() + 120
        while len(workers) < 2 and time.monotonic() < deadline and parent.poll() is None:
            time.sleep(0.2)
            workers = _children(parent.pid)
        assert len(workers) >= 2, "the workers did not start"
        time.sleep(2.0)  # let them get into their simulator start / first demo
        os.kill(parent.pid, signal.SIGKILL)
        parent.wait()
        deadline = time.monotonic() + 5.0
        while any(_alive(p) for p in workers) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not [p for p in workers if _alive(p)], "workers outlived their parent"
    finally:
        if parent.poll() is None:
            parent.kill()
        for p in workers:  # only the processes this test started, should the check above fail
            if _alive(p):
                os.kill(p, signal.SIGKILL)
