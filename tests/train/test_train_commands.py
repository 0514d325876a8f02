"""``pasta train reset | select | evaluate``: the policy-side stages in the one ``pasta train MODULE key=value`` style."""

import json

from pasta.cli import main


def test_missing_and_misspelt_keys_fail_before_any_work(tmp_path, capsys):
    assert main(["train", "reset", f"data={tmp_path}", f"out={tmp_path}"]) == 2
    assert "needs skill=NAME" in capsys.readouterr().err
    assert main(["train", "select", "skill=cut"]) == 2
    assert "`pasta train select` needs out=DIR" in capsys.readouterr().err
    assert main(["train", "select", f"out={tmp_path}", "skill=cut", "treshold=0.5"]) == 2
    assert "did you mean 'thresholds'" in capsys.readouterr().err
    assert main(["train", "reset", f"data={tmp_path}", f"out={tmp_path}", "skill=cut", "target=plane"]) == 2
    assert "target must be tool or skill" in capsys.readouterr().err
    assert main(["train", "evaluate", "controllers=learnd"]) == 2
    assert "did you mean 'learned'" in capsys.readouterr().err
    assert main(["train", "evaluate", "seeds=3"]) == 2
    assert "did you mean 'seed'" in capsys.readouterr().err
    assert not any(tmp_path.iterdir())


def test_train_reset_writes_beside_the_policy_of_the_models_root(tmp_path_factory, capsys):
    from synthetic_demos import write_knife_dataset

    data = write_knife_dataset(tmp_path_factory.mktemp("demos"))
    out = tmp_path_factory.mktemp("models")
    args = ["train", "reset", f"data={data}", f"out={out}", "skill=cut", "epochs=2", "batch_size=2", "points=32",
            "progress=false", "threads=1"]
    assert main(args) == 0
    metrics = json.loads(capsys.readouterr().out)
    assert metrics["module"] == "reset_pose" and metrics["train_demos"] == 2 and metrics["heldout_mae_m"] >= 0
    policy = out / "policy" / "cut"
    for name in ("reset.safetensors", "reset.json", "reset_last.safetensors", "reset_last.json", "reset_metrics.json"):
        assert (policy / name).is_file(), name
    assert json.loads((policy / "reset.json").read_text())["config"]["network"]["points"] == 32


def test_train_evaluate_prints_the_table_and_writes_the_records(tmp_path, capsys):
    small = ["n_grid=32", "n_particles=1500", "max_particles=1500", "obs_points=300"]  # the select stage test's simulator
    out = tmp_path / "eval.json"
    assert main(["train", "evaluate", "skills=push", "controllers=expert", "n=1", f"json={out}", *small]) == 0
    table = capsys.readouterr().out
    assert "| push | 1 | - | - | 1.000 (0.000) | - |" in table  # the expert reproduces its own goal exactly
    records = json.loads(out.read_text())
    assert list(records) == ["push"] and records["push"]["expert"][0]["ni"] == 1.0
