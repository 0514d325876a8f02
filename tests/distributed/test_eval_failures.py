"""`pasta eval` through the backend: an episode that raises is reported with its seed, the others are
written (by this process only), no summary is written, and the next run retries only the failed seed; the
episode deadline handed to the backend (``deadline_s=``, or derived from the task)."""

from __future__ import annotations

import argparse
import json

from pasta.execute.session import EpisodeOutcome


class _FakeSession:
    broken = {1001}

    def __init__(self, task):
        from pasta.config import load_config

        self.task, self.method, self.skill_choice = task, "pasta", None
        self.cfg = load_config(["task=push"])

    def describe(self):
        return {"task": self.task.name, "method": "pasta", "planner": "exhaustive", "controller": "heuristic",
                "skills": ["push"], "config": {"seed": 0}}

    def episode(self, seed, logger=None, sim=None):
        if seed in self.broken:
            raise RuntimeError(f"episode {seed} breaks on purpose")
        return EpisodeOutcome(self.task.name, "pasta", seed, improvement=0.5 + seed % 10 / 100, success=True)


def test_failed_episode_reported_with_its_seed_others_written_rerun_retries_it(tmp_path, monkeypatch, capsys):
    from pasta.commands import eval as eval_cmd
    from pasta.tasks import get_task

    task = get_task("push")
    task.make_sim = lambda: None  # no simulator: the bookkeeping is what is tested
    monkeypatch.setattr("pasta.execute.session.build_session", lambda *a, **k: _FakeSession(task))
    args = argparse.Namespace(overrides=["task=push", "num=3", f"out={tmp_path}"])
    assert eval_cmd.run(args) == 1
    err = capsys.readouterr().err
    assert "1 of 3 episodes of push / pasta failed" in err and "no summary written" in err
    assert "  seed 1001: raised RuntimeError: episode 1001 breaks on purpose" in err
    path = tmp_path / "push_pasta.jsonl"
    assert sorted(json.loads(x)["seed"] for x in path.read_text().splitlines()) == [1000, 1002]
    assert not path.with_suffix(".json").exists()
    _FakeSession.broken = set()
    try:
        assert eval_cmd.run(args) == 0
    finally:
        _FakeSession.broken = {1001}
    err = capsys.readouterr().err
    assert "3 test configs, 2 already in" in err and "seed 1001:" in err and "seed 1000:" not in err.split("already in")[1]
    assert sorted(json.loads(x)["seed"] for x in path.read_text().splitlines()) == [1000, 1001, 1002]
    assert json.loads(path.with_suffix(".json").read_text())["episodes"] == 3


def test_deadline_is_derived_from_the_task_or_given(tmp_path, monkeypatch):
    import pasta.distributed
    from pasta.commands import eval as eval_cmd
    from pasta.commands.eval import PLAN_S, episode_deadline
    from pasta.execute.session import build_session
    from pasta.tasks import get_task

    task = get_task("push")
    task.make_sim = lambda: None
    monkeypatch.setattr("pasta.execute.session.build_session", lambda *a, **k: _FakeSession(task))
    real, seen = pasta.distributed.map_jobs, []

    def spy(*args, **kwargs):
        seen.append(kwargs["deadline_s"])
        return real(*args, **kwargs)

    monkeypatch.setattr(pasta.distributed, "map_jobs", spy)
    _FakeSession.broken = set()
    try:
        assert eval_cmd.run(argparse.Namespace(overrides=["task=push", "num=1", f"out={tmp_path / 'a'}"])) == 0
        assert eval_cmd.run(argparse.Namespace(overrides=["task=push", "num=1", f"out={tmp_path / 'b'}",
                                                          "deadline_s=90"])) == 0
    finally:
        _FakeSession.broken = {1001}
    assert seen == [episode_deadline(_FakeSession(task)), 90.0]
    monkeypatch.undo()
    # push (horizon 1, skill.push.max_steps=80, 5,000 particles): 600 s of start-up + 1 s per step at most:
    # 10 settle + 80 + 10 idle to generate the instance, (80 + 40 overrun + 10 idle) x 2 (1 + execute.retries)
    assert episode_deadline(build_session("push", ["method=oracle"])) == 600 + 100 + 260
    assert episode_deadline(build_session("push", ["method=oracle", "execute.retries=0"])) == 600 + 100 + 130
    assert episode_deadline(build_session("push", ["method=oracle", "task.n_particles=10000"])) == 600 + 2 * 360
    # a planning method: PLAN_S per horizon step, every skill planned with at the longest step limit of the skills the
    # scene allows: the push task has no board, so not the lift's 160 but the cut's 130
    assert episode_deadline(build_session("push")) == 600 + PLAN_S + (10 + 140) + (130 + 50) * 2
    # lift_spread (horizon 2, the board stands): the lift's 160
    assert episode_deadline(build_session("lift_spread")) == 600 + 2 * PLAN_S + (10 + 2 * 170) + (160 + 50) * 2 * 2


def test_episode_lines_end_with_an_eta(tmp_path, monkeypatch, capsys):
    import re

    from pasta.commands import eval as eval_cmd
    from pasta.tasks import get_task

    task = get_task("push")
    task.make_sim = lambda: None
    monkeypatch.setattr("pasta.execute.session.build_session", lambda *a, **k: _FakeSession(task))
    _FakeSession.broken = set()
    try:
        assert eval_cmd.run(argparse.Namespace(overrides=["task=push", "num=3", f"out={tmp_path}"])) == 0
    finally:
        _FakeSession.broken = {1001}
    lines = [line for line in capsys.readouterr().err.splitlines() if line.startswith("[")]
    assert [bool(re.search(r", ETA \d+s$", line)) for line in lines] == [True, True, False], lines  # none after the last


def test_eta_is_the_mean_episode_time_times_the_episodes_left_over_the_workers():
    from pasta.commands._progress import duration, eta

    assert eta([100.0, 300.0], 2, workers=2) == "ETA 3m20s"
    assert eta([60.0], 3) == "ETA 3m00s"
    assert eta([], 5) == "" and eta([10.0], 0) == ""
    assert (duration(0.4), duration(45.4), duration(200), duration(7500)) == ("0s", "45s", "3m20s", "2h05m")
