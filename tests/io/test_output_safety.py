"""Outputs of the simulator commands (issue 41): never written through a link, and one writer per output (a
killed run's log: tests/io/test_crash_safe_run.py).

The link tests run a command once into a fresh folder to learn every name it writes, plant a link at each
(and at the temporary names beside it) to a file outside ``out=``, run it again and check that nothing
outside changed (tests/output_links.py).
"""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from output_links import assert_regular, assert_untouched, plant_links, written_files
from pasta_runs import RUN, start_run
from pasta.cli import main
from pasta.io import RunReader, partial_path

# a short planner and episode: what is written is tested, not how good it is
EVAL = ["eval", "task=push", "num=1", "planner.num_samples=32", "planner.iterations=20", "skill.push.max_steps=25"]
DEMOS = ["demos", "skill=push", "num=1", "workers=0", "n_particles=1500", "obs_points=300"]


@pytest.mark.sim
def test_run_and_replay_export_never_write_through_a_link(tmp_path, capsys):
    first, out = tmp_path / "first", tmp_path / "out"
    assert main([*RUN, f"log={first / 'run.mcap'}", f"summary={first / 'summary.png'}"]) == 0
    assert main(["replay", str(first / "run.mcap"), f"export={first / 'frames'}", "max_frames=2"]) == 0
    names = written_files(first)
    assert {"run.mcap", "summary.png"} <= set(names) and any(n.startswith("frames/") for n in names)
    planted = plant_links(out, names, tmp_path / "victims")
    assert main([*RUN, f"log={out / 'run.mcap'}", f"summary={out / 'summary.png'}"]) == 0
    assert main(["replay", str(out / "run.mcap"), f"export={out / 'frames'}", "max_frames=2"]) == 0
    assert_untouched(planted)
    assert_regular(out, names)
    assert RunReader(out / "run.mcap").status == "complete"


@pytest.mark.sim
def test_eval_never_writes_through_a_link_and_refuses_one_at_its_result_file(tmp_path, capsys):
    first, out = tmp_path / "first", tmp_path / "out"
    assert main([*EVAL, f"out={first}"]) == 0
    names = written_files(first)
    assert sorted(Path(n).suffix for n in names) == [".json", ".jsonl"]
    (summary,) = [n for n in names if n.endswith(".json")]
    planted = plant_links(out, [summary], tmp_path / "victims")
    assert main([*EVAL, f"out={out}"]) == 0  # the summary's link is replaced by the summary
    assert_untouched(planted)
    assert_regular(out, names)
    capsys.readouterr()
    # the result file is appended to (resume): a link there is refused before any episode, not followed
    (rows,) = [n for n in names if n.endswith(".jsonl")]
    again = tmp_path / "again"
    planted = plant_links(again, [rows], tmp_path / "victims2", temps=False)
    assert main([*EVAL, f"out={again}"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) >= 1 and "is a symbolic link; pasta does not write through links" in err[-1]
    assert "eval push" not in "\n".join(err)  # refused before the evaluation started
    assert_untouched(planted)


@pytest.mark.sim
def test_demos_never_write_through_a_link(tmp_path):
    first, out = tmp_path / "first", tmp_path / "out"
    assert main([*DEMOS, f"out={first}"]) == 0
    names = written_files(first)
    assert "push/demo_00000.npz" in names and "manifest.json" in names
    planted = plant_links(out, names, tmp_path / "victims")
    assert main([*DEMOS, f"out={out}"]) == 0  # the planted demo is a link, not a demo: it is made again
    assert_untouched(planted)
    assert_regular(out, names)


@pytest.mark.sim
def test_a_second_run_on_the_same_log_is_refused_at_start_and_the_first_stays_intact(tmp_path):
    log = tmp_path / "conc.mcap"
    first = start_run(log, 1000)
    try:
        deadline = time.monotonic() + 120
        while not partial_path(log).exists() and time.monotonic() < deadline and first.poll() is None:
            time.sleep(0.2)
        assert partial_path(log).exists(), "the first run did not start its log"
        t0 = time.monotonic()
        second = start_run(log, 1001)
        out, err = second.communicate(timeout=120)
        assert second.returncode == 2
        lines = err.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("pasta run: error: log=") and "in use by another pasta process" in lines[0]
        assert f"pid {first.pid}" in lines[0]
        assert time.monotonic() - t0 < 60  # refused at start, not after an episode (a hang guard, not a speed test)
        out, err = first.communicate(timeout=600)
        assert first.returncode == 0, err
    finally:
        if first.poll() is None:
            first.kill()
            first.wait()
    reader = RunReader(log)
    assert reader.status == "complete" and reader.metadata()["seed"] == "1000"
    assert not partial_path(log).exists()
