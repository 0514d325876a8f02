"""The oracle (`pasta eval method=oracle`): its arguments are checked before any work; `split=val` runs the
validation seeds, and every row records its provenance."""

import json

import pytest

from pasta.cli import main


def test_bad_split_and_output_fail_before_any_work(tmp_path, capsys):
    assert main(["eval", "task=push", "method=oracle", "num=1", "split=train", f"out={tmp_path}"]) == 2
    assert "split=train: must be one of test, val" in capsys.readouterr().err
    (tmp_path / "taken").write_text("a file")
    assert main(["eval", "task=push", "method=oracle", "num=1", f"out={tmp_path / 'taken'}"]) == 2
    assert "out=" in capsys.readouterr().err


@pytest.mark.sim
def test_validation_split_writes_seeds_and_provenance(tmp_path):
    assert main(["eval", "task=push", "method=oracle", "num=1", "split=val", f"out={tmp_path}"]) == 0
    rows = [json.loads(x) for x in (tmp_path / "push_oracle_val.jsonl").read_text().splitlines()]
    assert [r["seed"] for r in rows] == [2000] and rows[0]["success"] in (True, False)
    summary = json.loads((tmp_path / "push_oracle_val.json").read_text())
    assert summary["split"] == "val" and summary["method"] == "oracle"
    assert summary["provenance"]["packages"]["taichi"] and "fast_math" in json.dumps(summary["provenance"])
