"""benchmarks/rerun_results.py: it re-makes exactly the rows the tables cite, under the names ``pasta eval`` gives
them, resumes, and flags a row that lost more than one success."""

from __future__ import annotations

import importlib
import json
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture()
def rerun(monkeypatch):
    monkeypatch.syspath_prepend(str(ROOT / "benchmarks"))
    for name in ("rerun_results", "results_table"):
        sys.modules.pop(name, None)
    return importlib.import_module("rerun_results")


def test_rows_are_the_cited_rows(rerun):
    import results_table as rt

    cited = {f"{task}_pasta{suffix}" for task, _, _ in rt.TASKS for suffix in ("", "_learned")}
    cited |= {name for _, _, name, _, _ in rt.ABLATIONS} | set(rt.loop_names()) | set(rt.plugin_names())
    cited |= set(rt.trajopt_names())
    names = [row.name for row in rt.rows()]
    assert len(names) == len(set(names)) and set(names) == cited


def test_each_eval_row_is_named_as_pasta_eval_names_it(rerun):
    from pasta.commands.eval import EvalArgs, result_path
    from pasta.commands.run import split_command_keys
    from pasta.config import load_config

    for row in rerun.rows():
        if row.script:
            assert (ROOT / row.script).exists(), row
            continue
        argv = rerun.command(row, Path("/tmp/out"))
        assert argv[1:4] == ["-m", "pasta", "eval"] and "threads=1" in argv and argv[-1] == "out=/tmp/out"
        _, rest = split_command_keys(list(row.settings), EvalArgs)
        assert result_path("/tmp/out", load_config(rest), rest).stem == row.name, row
        assert f"num={row.configs}" in row.settings


def _summary(folder: Path, name: str, wins: int, episodes: int = 20) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / f"{name}.json").write_text(json.dumps(
        {"episodes": episodes, "split": "test", "success_rate": wins / episodes, "improvement_mean": wins / episodes}))
    (folder / f"{name}.jsonl").write_text("".join(json.dumps({"seed": 1000 + i, "wall_s": 1.0}) + "\n"
                                                  for i in range(episodes)))


def test_compare_flags_only_a_loss_of_more_than_one_success(rerun, tmp_path, monkeypatch, capsys):
    old, new = tmp_path / "old", tmp_path / "new"
    monkeypatch.setattr(rerun, "RESULTS", old)
    a, b, c = (row.name for row in rerun.rows()[:3])
    for name, before, after in ((a, 20, 19), (b, 18, 16)):
        _summary(old, name, before)
        _summary(new, name, after)
    _summary(old, c, 20)  # not made again yet
    assert rerun.main(["compare", str(new), "--only", a]) == 0
    assert rerun.main(["compare", str(new), "--only", a, b, c]) == 1
    printed = capsys.readouterr().out
    assert f"| {b} | 18/20 | 16/20 | -2 **lost more than one** |" in printed
    assert "2 rows compared, 1 not made yet; 1 lost more than one success: " + b in printed


def test_run_makes_missing_rows_and_resumes(rerun, tmp_path, monkeypatch, capsys):
    row = rerun.rows()[0]
    writes = (f"import json, pathlib; p = pathlib.Path({str(tmp_path)!r}); "
              f"(p / '{row.name}.json').write_text(json.dumps({{'episodes': 20, 'success_rate': 0.5, "
              f"'improvement_mean': 0.5}})); (p / '{row.name}.jsonl').write_text('')")
    launched = []

    def fake(r, out):
        launched.append(r.name)
        return [sys.executable, "-c", writes]

    monkeypatch.setattr(rerun, "command", fake)
    assert rerun.main(["run", str(tmp_path), "--only", row.name, "--poll", "0.05"]) == 0
    assert launched == [row.name] and "finished " + row.name + ": 10/20 successes" in capsys.readouterr().out
    assert rerun.main(["run", str(tmp_path), "--only", row.name, "--poll", "0.05"]) == 0
    assert launched == [row.name] and "done already: " + row.name in capsys.readouterr().out


def test_a_failing_row_is_reported_and_fails_the_run(rerun, tmp_path, monkeypatch, capsys):
    row = rerun.rows()[0]
    monkeypatch.setattr(rerun, "command", lambda r, out: [sys.executable, "-c", "raise SystemExit(3)"])
    assert rerun.main(["run", str(tmp_path), "--only", row.name, "--poll", "0.05"]) == 1
    assert f"FAILED {row.name} (exit 3" in capsys.readouterr().out


def test_only_with_no_match_names_the_problem(rerun, tmp_path):
    with pytest.raises(SystemExit, match="no row matches"):
        rerun.main(["compare", str(tmp_path), "--only", "no_such_row*"])
