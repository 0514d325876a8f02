"""Demonstration generation (argument checks, a 3-demo dataset read back by the shared reader)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from pasta.cli import main
from pasta.core.errors import ConfigError, InputError
from pasta.demos import DemoConfig, demo_skills, generate_demos, validate


def test_bad_arguments_fail_before_any_work(tmp_path, capsys):
    # the messages list every skill that can make demonstrations, the built-ins among them
    known = ", ".join(demo_skills())
    assert {"cut", "push", "roll"} <= set(demo_skills())
    with pytest.raises(ConfigError, match=f"unknown skill 'knead'.*skills with demonstrations: {known}$"):
        validate(DemoConfig(skill="knead", out=str(tmp_path)))
    with pytest.raises(ConfigError, match=f"needs skill=NAME; skills with demonstrations: {known}$"):
        validate(DemoConfig(out=str(tmp_path)))
    with pytest.raises(ConfigError, match=r"num=0: must be an integer in \[1, "):
        validate(DemoConfig(skill="cut", num=0, out=str(tmp_path)))
    with pytest.raises(ConfigError, match=r"seed=-1: must be an integer in \[0, "):
        validate(DemoConfig(skill="cut", seed=-1, out=str(tmp_path)))
    with pytest.raises(ConfigError, match=r"n_particles=0: must be in \[1, "):
        validate(DemoConfig(skill="cut", n_particles=0, out=str(tmp_path)))
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(ConfigError, match="is a file, so the path cannot be created"):
        validate(DemoConfig(skill="cut", out=str(blocker / "sub")))
    validate(DemoConfig(skill="cut", out=str(tmp_path / "new")))
    assert not (tmp_path / "new").exists()  # checks create nothing
    assert main(["demos", "skill=knead", f"out={tmp_path}"]) == 2
    assert f"skills with demonstrations: {known}" in capsys.readouterr().err
    assert main(["demos", "skill=cut", "num=-3", f"out={tmp_path}"]) == 2
    assert main(["demos", "bogus=1"]) == 2
    assert not list(tmp_path.glob("*/demo_*.npz"))


@pytest.mark.sim
def test_generate_and_load_three_demos(tmp_path):
    cfg = DemoConfig(skill="push", num=3, out=str(tmp_path), workers=0, seed=5, n_particles=2000, obs_points=400)
    summary = generate_demos(cfg, progress=False)
    assert summary["generated"] == 3 and summary["skipped"] == 0
    files = sorted((tmp_path / "push").glob("demo_*.npz"))
    assert [f.name for f in files] == ["demo_00000.npz", "demo_00001.npz", "demo_00002.npz"]
    with np.load(files[0], allow_pickle=False) as z:
        t = z["action"].shape[0]
        assert t > 5 and z["action"].shape == (t, 4) and z["action"].dtype == np.float32
        assert z["dough"].shape == (t + 1, 400, 3) and z["dough"].dtype == np.float32
        assert z["tool_points"].shape[0] == t + 1 and z["tool_pose"].shape == (t + 1, 7)
        assert z["skill"].shape == () and str(z["skill"]) == "push"
        params = json.loads(str(z["params"]))
        assert {"target_x", "target_z"} <= set(params)
        assert np.abs(z["action"]).max() <= 1.0
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    assert manifest["counts"] == {"push": 3} and "taichi" in manifest["versions"]
    # resumable: nothing left to do; a deleted demo is regenerated identically
    first = files[1].read_bytes()
    files[1].unlink()
    again = generate_demos(cfg, progress=False)
    assert again["generated"] == 1 and again["skipped"] == 2
    assert files[1].read_bytes() == first

    from pasta.demos.data import load_demos  # the one reader every trainer uses

    demos = load_demos(tmp_path, ["push"])
    assert len(demos) == 3 and demos[0].skill == "push"
    assert demos[0].dough.shape[1:] == (400, 3) and demos[0].action.shape[1] == 4
    with pytest.raises(InputError, match="no demonstrations"):
        load_demos(tmp_path, ["cut"])


def test_reader_errors(tmp_path):
    from pasta.demos.data import load_demos

    with pytest.raises(InputError, match="not a pasta dataset: no manifest.json; generate demonstrations"):
        load_demos(tmp_path)
    (tmp_path / "knead").mkdir()
    (tmp_path / "knead" / "demo_00000.npz").write_bytes(b"")
    # a folder of demonstrations without its manifest: the error names the command that writes it
    with pytest.raises(InputError, match=f"`pasta demos skill=knead num=N out={tmp_path}` writes it"):
        load_demos(tmp_path)


def test_threads_set_the_simulators_cpu_threads():
    from pasta.demos.generate import sim_config
    from pasta.sim import SimConfig

    assert sim_config(DemoConfig(skill="push", threads=3)).cpu_threads == 3
    assert sim_config(DemoConfig(skill="push")).cpu_threads == SimConfig().cpu_threads  # 0: the simulator's default


@pytest.mark.sim
def test_cli_prints_no_bar_into_a_pipe_and_threads_do_not_change_a_demo(tmp_path):
    """`pasta demos` with stdout and stderr piped: the result line and no progress bar (rich would print its
    last state once); a demo made with 1 simulator thread is byte for byte the one made with 2 (threads= is
    no part of the pipeline's settings, pasta.pipeline.run.IGNORED). Separate processes: Taichi takes its
    thread count once per process."""
    import subprocess
    import sys

    base = [sys.executable, "-m", "pasta", "demos", "skill=push", "num=1", "workers=0", "n_particles=1500",
            "obs_points=300"]
    for threads in (1, 2):
        done = subprocess.run([*base, f"out={tmp_path / str(threads)}", f"threads={threads}"], capture_output=True,
                              text=True, timeout=600)
        assert done.returncode == 0, done.stderr
        assert not any(c in done.stdout + done.stderr for c in "━╸╺%"), (done.stdout, done.stderr)  # rich's bar
        ours = [line for line in done.stdout.splitlines() if not line.startswith("[Taichi]")]
        assert len(ours) == 1 and ours[0].startswith("demos push: 1 generated"), done.stdout
    assert (tmp_path / "1" / "push" / "demo_00000.npz").read_bytes() == \
        (tmp_path / "2" / "push" / "demo_00000.npz").read_bytes()
