"""`pasta eval` through the backend: an episode that raises is reported with its seed, the others are
written (by this process only), no summary is written, and the next run retries only the failed seed."""

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
    assert "  seed 1001: raised an exception:" in err and "RuntimeError: episode 1001 breaks on purpose" in err
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
