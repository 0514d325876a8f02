"""`pasta oracle` arguments are checked before any work; `split=val` runs the validation seeds."""

import json

import pytest

from pasta.cli import main


def test_bad_split_and_unwritable_json_fail_before_any_work(tmp_path, capsys):
    assert main(["oracle", "task=push", "num=1", "split=train"]) == 2
    assert "split=train: must be one of test, val" in capsys.readouterr().err
    assert main(["oracle", "task=push", "num=1", f"json={tmp_path}"]) == 2  # a directory, not a file
    assert "json=" in capsys.readouterr().err


@pytest.mark.sim
def test_validation_split_writes_seeds_and_provenance(tmp_path):
    out = tmp_path / "sub" / "oracle.json"
    assert main(["oracle", "task=push", "num=1", "split=val", f"json={out}"]) == 0
    doc = json.loads(out.read_text())
    assert doc["split"] == "val" and [e["seed"] for e in doc["episodes"]] == [2000]
    assert doc["provenance"]["packages"]["taichi"] and "fast_math" in json.dumps(doc["provenance"])
