"""Every `pasta eval` result row and every `pasta run` log records its provenance (issue 21)."""

from __future__ import annotations

import argparse
import json
from pasta.execute.session import EpisodeOutcome


SETUP = {"task": "push", "method": "pasta", "planner": "exhaustive", "controller": "heuristic", "skills": ["push"],
         "config": {"seed": 4}}


class _FakeSession:
    def __init__(self, task):
        from pasta.config import load_config

        self.task, self.method, self.skill_choice = task, "pasta", None
        self.cfg = load_config(["task=push", "seed=4"])

    def describe(self):
        return dict(SETUP)

    def episode(self, seed, logger=None, sim=None):
        return EpisodeOutcome(self.task.name, "pasta", seed, improvement=0.9, success=True)


def _fake(monkeypatch):
    from pasta.tasks import get_task

    task = get_task("push")
    task.make_sim = lambda: None  # no simulator: the record is what is tested
    monkeypatch.setattr("pasta.execute.session.build_session", lambda *a, **k: _FakeSession(task))


def test_eval_rows_and_summary_record_provenance(tmp_path, monkeypatch):
    from pasta.commands import eval as eval_cmd

    _fake(monkeypatch)
    assert eval_cmd.run(argparse.Namespace(overrides=["task=push", "num=2", f"out={tmp_path}"])) == 0
    rows = [json.loads(x) for x in (tmp_path / "push_pasta.jsonl").read_text().splitlines()]
    assert len(rows) == 2
    for row in rows:
        rec = row["provenance"]
        assert rec["packages"]["taichi"] and rec["packages"]["torch"] and rec["cpu"]["model"]
        assert "fast_math" in rec["taichi"] and "arch" in rec["taichi"]
    assert json.loads((tmp_path / "push_pasta.json").read_text())["provenance"]["packages"] == rows[0]["provenance"]["packages"]


def test_run_log_has_a_provenance_record(tmp_path, monkeypatch):
    from pasta.commands import run as run_cmd
    from pasta.io import RunReader
    from pasta.io.provenance import PROVENANCE_RECORD

    _fake(monkeypatch)
    log = tmp_path / "r.mcap"
    assert run_cmd.run(argparse.Namespace(overrides=["task=push", f"log={log}"])) == 0
    with RunReader(log) as reader:
        rec = reader.metadata(PROVENANCE_RECORD)
    assert rec["packages.numpy"] and rec["cpu.model"] and rec["taichi.fast_math"] in ("true", "false")
    assert rec["python"]


def test_eval_resume_refuses_a_damaged_results_file(tmp_path, monkeypatch):
    import pytest

    from pasta.commands import eval as eval_cmd
    from pasta.core.errors import ConfigError

    _fake(monkeypatch)
    first = {"seed": 1000, "improvement": 0.5, "success": False, "setup": SETUP}
    (tmp_path / "push_pasta.jsonl").write_text(json.dumps(first) + '\n{"seed": 10')
    with pytest.raises(ConfigError, match=r"line 2 of .*push_pasta.jsonl is not a result row .*resume=false"):
        eval_cmd.run(argparse.Namespace(overrides=["task=push", "num=2", f"out={tmp_path}"]))
