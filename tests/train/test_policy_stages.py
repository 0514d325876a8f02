"""``pasta pipeline`` stages ``reset`` and ``select``: the cut's reset pose and the stopping rules, after the
policies, as resumable units (tiny sizes; the select unit runs the real simulator on a 32^3 grid)."""

import json

import pytest

from pasta.core.errors import ConfigError
from pasta.pipeline import PipelineConfig, parse_arguments, plan, run_pipeline
from synthetic_demos import write_knife_dataset


@pytest.fixture(scope="module")
def knife_demos(tmp_path_factory):
    return write_knife_dataset(tmp_path_factory.mktemp("knife_demos"))

TINY_POLICY = {"epochs": "1", "steps_per_epoch": "2", "val_batches": "1", "batch_size": "4", "dough_points": "32",
               "tool_points": "8", "goal_points": "32"}
TINY_RESET = {"epochs": "2", "batch_size": "4"}
#: one validation config, a short rollout, a small simulator
TINY_SELECT = {"n": "1", "learned_max_steps": "3", "thresholds": "0.5", "min_steps": "1", "max_steps": "0,2",
               "n_grid": "32", "n_particles": "1500", "max_particles": "1500", "obs_points": "300", "progress": "false"}
UNITS = ("policy/cut", "reset/cut", "select/cut")


def _args(data, out, *extra):
    stage_args = [f"{stage}.{k}={v}" for stage, values in (("policy", TINY_POLICY), ("reset", TINY_RESET),
                                                           ("select", TINY_SELECT)) for k, v in values.items()]
    return [f"data={data}", f"out={out}", "stages=policy,reset,select", "skills=cut", "progress=false",
            *stage_args, *extra]


def _status(results):
    return {r.name: r.status for r in results}


def test_default_plan_adds_reset_for_cut_and_select_for_cut_and_roll():
    from pasta.plugins import get_plugins

    names = [u.name for u in plan(*parse_arguments(["stages=policy,reset,select"]))]
    # a policy for every registered skill, then the reset and select units in stage order
    later = [n for n in names if not n.startswith("policy/")]
    assert names == [f"policy/{s}" for s in get_plugins().skills.names()] + later
    stages = [n.split("/")[0] for n in later]
    assert stages == ["reset"] * stages.count("reset") + ["select"] * stages.count("select")
    # among the built-ins: reset for cut, select for cut and roll
    builtin = [n for n in later if n.split("/")[1] in ("cut", "push", "roll")]
    assert builtin == ["reset/cut", "select/cut", "select/roll"]
    units = {u.name: u for u in plan(PipelineConfig(stages="reset,select"), {})}
    (loop, reset), cut, roll = units["reset/cut"].configs, units["select/cut"].configs[0], units["select/roll"].configs[0]
    # the shipped regressor's settings: the trainer's defaults (epochs, start_step, points) and the cut plugin's own
    assert (loop.epochs, reset.start_step, reset.points) == (90, 0, 1000)
    assert (reset.target, reset.piece_share, reset.decoded_goals, reset.decoded_noise) == ("skill", True, 0.5, 0.5)
    policy = {u.name: u for u in plan(PipelineConfig(stages="policy"), {})}
    assert policy["policy/cut"].configs[1].start_at_reset and not policy["policy/roll"].configs[1].start_at_reset
    assert (cut.n, cut.seed, cut.write) == (20, 2000, True)  # validation configs, never the test seed 1000
    assert cut.max_steps == "0,40,45,50,55,60,65,70,80,100" and roll.min_steps == "1,20"
    assert str(units["select/cut"].directory).endswith("policy/cut")
    names = [u.name for u in plan(PipelineConfig(stages="reset,select", select_skills="roll", reset_skills=""), {})]
    assert names == ["select/roll"]


def test_bad_settings_fail_before_any_work(knife_demos, tmp_path):
    out = tmp_path / "models"
    with pytest.raises(ConfigError, match="did you mean 'thresholds'"):
        run_pipeline(_args(knife_demos, out, "select.treshold=0.5"))
    with pytest.raises(ConfigError, match="did you mean 'epochs'"):
        run_pipeline(_args(knife_demos, out, "reset.epoch=3"))
    with pytest.raises(ConfigError, match="comma-separated numbers"):
        run_pipeline(_args(knife_demos, out, "select.max_steps=0,x"))
    with pytest.raises(ConfigError, match="unknown skill 'cutt'"):
        run_pipeline(_args(knife_demos, out, "reset_skills=cutt"))
    with pytest.raises(ConfigError, match="select.skill is set by the pipeline"):
        run_pipeline(_args(knife_demos, out, "select.skill=roll"))
    with pytest.raises(ConfigError, match="needs a trained policy"):
        run_pipeline(_args(knife_demos, out, "stages=select"))
    assert not out.exists()


def test_reset_and_select_run_after_the_policy_then_skip_and_rerun_only_what_changed(knife_demos, tmp_path):
    lines = []
    results = run_pipeline(_args(knife_demos, tmp_path), echo=lines.append)
    assert _status(results) == dict.fromkeys(UNITS, "ran")
    policy = tmp_path / "policy" / "cut"
    for name in ("model.safetensors", "metrics.json", "reset.safetensors", "reset.json", "reset_metrics.json",
                 "select.json"):
        assert (policy / name).is_file(), name
    assert not (policy / "select.partial.jsonl").exists()
    assert "[2/3] reset/cut ..." in lines
    assert any(line.startswith("[2/3] reset/cut done in") and "heldout_mae_m" in line for line in lines)
    assert any(line.startswith("[3/3] select/cut done in") and "mean_ni" in line and "rule 0.5, 1," in line
               for line in lines)
    assert "3 ran, 0 skipped" in lines[-1]

    # the selected rule went into the policy's model.json; the reset regressor's settings into reset.json
    selected = json.loads((policy / "select.json").read_text())
    rule = json.loads((policy / "model.json").read_text())["config"]["controller"]
    assert rule == {k: selected["selected"][k] for k in ("done_threshold", "min_steps", "max_steps")}
    assert selected["seed"] == 2000 and len(selected["ni"]) == 1 and len(selected["ni"][0]) == 2  # 1 config x 2 rules
    assert json.loads((policy / "reset.json").read_text())["config"]["network"]["start_step"] == 0
    record = json.loads((tmp_path / "pipeline.json").read_text())["units"]
    assert record["reset/cut"]["settings"]["config"]["epochs"] == 2
    assert record["reset/cut"]["settings"]["demos"] == {"cut": 3}
    assert record["select/cut"]["settings"]["config"]["seed"] == 2000
    assert record["select/cut"]["settings"]["weights"]["reset.safetensors"] != "missing"
    assert record["select/cut"]["status"] == "done"

    assert _status(run_pipeline(_args(knife_demos, tmp_path), echo=lines.append)) == dict.fromkeys(UNITS, "skipped")
    # a select setting: only select reruns (threads never does)
    changed = ("select.thresholds=0.4,0.6", "reset.threads=0")
    assert _status(run_pipeline(_args(knife_demos, tmp_path, *changed), echo=lines.append)) == {
        **dict.fromkeys(UNITS, "skipped"), "select/cut": "ran"}
    assert len(json.loads((policy / "select.json").read_text())["rules"]) == 4
    # a retrained policy (new weights, a model.json without a rule) is reselected; the reset pose is kept
    changed = (*changed, "policy.cut.val_batches=2", "policy.seed=1")
    assert _status(run_pipeline(_args(knife_demos, tmp_path, *changed), echo=lines.append)) == {
        "policy/cut": "ran", "reset/cut": "skipped", "select/cut": "ran"}
    assert json.loads((policy / "model.json").read_text())["config"]["controller"]["done_threshold"] in (0.4, 0.6)
    # a model.json that lost its rule (the policy retrained to the same weights) reselects too
    doc = json.loads((policy / "model.json").read_text())
    del doc["config"]["controller"]
    (policy / "model.json").write_text(json.dumps(doc))
    assert _status(run_pipeline(_args(knife_demos, tmp_path, *changed), echo=lines.append)) == {
        **dict.fromkeys(UNITS, "skipped"), "select/cut": "ran"}
    # a changed reset setting retrains the regressor, whose new weights rerun select; the policy stays
    results = run_pipeline(_args(knife_demos, tmp_path, *changed, "reset.seed=3"), echo=lines.append)
    assert _status(results) == {"policy/cut": "skipped", "reset/cut": "ran", "select/cut": "ran"}
    assert (policy / "metrics.json").is_file() and (policy / "last.safetensors").is_file()  # the policy's own files


def test_an_interrupted_select_resumes_at_the_next_config(knife_demos, tmp_path, monkeypatch):
    import pasta.train.select as select

    args = _args(knife_demos, tmp_path, "select.n=2", "stages=policy,reset")
    assert _status(run_pipeline(args, echo=lambda _: None)) == {"policy/cut": "ran", "reset/cut": "ran"}
    args = [a for a in args if not a.startswith("stages=")] + ["stages=select"]
    real, seen = select.sweep, []

    def sweep(sim, skill, configs, *a, **kw):
        seen.append(configs[0].seed)
        if len(seen) == 2 and interrupt:
            raise KeyboardInterrupt
        return real(sim, skill, configs, *a, **kw)

    monkeypatch.setattr(select, "sweep", sweep)
    interrupt = True
    with pytest.raises(KeyboardInterrupt):
        run_pipeline(args, echo=lambda _: None)
    policy = tmp_path / "policy" / "cut"
    assert not (policy / "select.json").exists() and (policy / "select.partial.jsonl").is_file()
    assert json.loads((tmp_path / "pipeline.json").read_text())["units"]["select/cut"]["status"] == "running"
    interrupt, lines = False, []
    assert _status(run_pipeline(args, echo=lines.append)) == {"select/cut": "ran"}
    assert "[1/1] select/cut ... resuming (1 of 2 configs scored)" in lines
    assert seen == [0, 1, 1]  # config 0 was not scored again
    resumed = json.loads((policy / "select.json").read_text())
    # the same result as an uninterrupted run
    seen.clear()
    assert _status(run_pipeline([*args, "force=true"], echo=lambda _: None)) == {"select/cut": "ran"}
    assert seen == [0, 1]
    assert json.loads((policy / "select.json").read_text())["ni"] == resumed["ni"]
