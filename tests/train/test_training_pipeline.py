"""``pasta pipeline``: every unit trains once, done units are skipped, changed ones rerun, typos fail early."""

import json

import numpy as np
import pytest

from pasta.cli import main
from pasta.core.errors import ConfigError
from pasta.pipeline import run_pipeline

TINY_POLICY = {"epochs": "1", "steps_per_epoch": "2", "val_batches": "1", "batch_size": "4", "dough_points": "32",
               "tool_points": "8", "goal_points": "32"}
UNITS = ("vae", "feasibility/cut", "cost", "policy/cut")


def _args(data, out, tiny, *extra):
    stage_args = [f"{stage}.{k}={v}" for stage, values in (*tiny.items(), ("policy", TINY_POLICY))
                  for k, v in values.items()]
    return [f"data={data}", f"out={out}", "stages=vae,feasibility,cost,policy", "skills=cut", "progress=false",
            *stage_args, *extra]


def _status(results):
    return {r.name: r.status for r in results}


def test_units_train_once_then_skip_and_rerun_only_what_changed(three_demos, tmp_path, tiny):
    lines = []
    results = run_pipeline(_args(three_demos, tmp_path, tiny), echo=lines.append)
    assert _status(results) == dict.fromkeys(UNITS, "ran")
    for unit in UNITS:
        assert (tmp_path / unit / "metrics.json").is_file()
    assert "[2/4] feasibility/cut ..." in lines
    assert any(line.startswith("[2/4] feasibility/cut done in") and "heldout_auc_hard" in line for line in lines)
    assert "4 ran, 0 skipped" in lines[-1]  # the summary table
    record = json.loads((tmp_path / "pipeline.json").read_text())["units"]
    assert record["feasibility/cut"]["settings"]["config"]["stride"] == 3  # the pipeline's per-skill default
    assert record["feasibility/cut"]["settings"]["config"]["epochs"] == 2  # tiny's stage setting over it
    assert record["cost"]["settings"]["vae"]["weights"] != "missing"

    lines.clear()
    results = run_pipeline(_args(three_demos, tmp_path, tiny), echo=lines.append)
    assert _status(results) == dict.fromkeys(UNITS, "skipped")
    assert any(line.startswith("[1/4] vae skipped") for line in lines)

    # one setting changed: that unit only reruns (from scratch); threads never causes a rerun
    results = run_pipeline(_args(three_demos, tmp_path, tiny, "cost.epochs=1", "vae.threads=2"), echo=lines.append)
    assert _status(results) == {**dict.fromkeys(UNITS, "skipped"), "cost": "ran"}
    assert json.loads((tmp_path / "cost" / "metrics.json").read_text())["best_epoch"] == 0
    # a per-skill setting reaches its unit only
    changed = ("cost.epochs=1", "policy.cut.val_batches=2")
    results = run_pipeline(_args(three_demos, tmp_path, tiny, *changed), echo=lines.append)
    assert _status(results) == {**dict.fromkeys(UNITS, "skipped"), "policy/cut": "ran"}

    # interrupted (no metrics.json, same settings): resumes from last.*; only= and force= select and rerun
    (tmp_path / "cost" / "metrics.json").unlink()
    lines.clear()
    results = run_pipeline(_args(three_demos, tmp_path, tiny, *changed, "only=cost"), echo=lines.append)
    assert _status(results) == {"cost": "ran"}
    assert any("resuming from last.* (1 of 1 epochs done)" in line for line in lines)
    results = run_pipeline(_args(three_demos, tmp_path, tiny, *changed, "only=feasibility", "force=true"),
                           echo=lines.append)
    assert _status(results) == {"feasibility/cut": "ran"}


def test_bad_arguments_fail_before_any_work(three_demos, tmp_path, tiny):
    out = tmp_path / "models"
    with pytest.raises(ConfigError, match="did you mean 'epochs'"):
        run_pipeline(_args(three_demos, out, tiny, "feasibility.epoch=3"))
    with pytest.raises(ConfigError, match="did you mean 'hidden'"):
        run_pipeline(_args(three_demos, out, tiny, "cost.hiden=8"))
    with pytest.raises(ConfigError, match="unknown stage 'vea'; did you mean 'vae'.*known stages: demos, vae"):
        run_pipeline(_args(three_demos, out, tiny, "stages=vea"))
    with pytest.raises(ConfigError, match="unknown stage 'polcy'"):
        run_pipeline(_args(three_demos, out, tiny, "polcy.epochs=3"))
    from pasta.plugins import get_plugins

    known = get_plugins().skills.names()  # every registered skill, the built-ins among them
    assert {"cut", "push", "roll"} <= set(known)
    with pytest.raises(ConfigError, match=f"unknown skill 'cutt'.*known skills: {', '.join(known)}$"):
        run_pipeline(_args(three_demos, out, tiny, "skills=cut,cutt"))
    with pytest.raises(ConfigError, match="did you mean 'num_demos'"):
        run_pipeline(_args(three_demos, out, tiny, "num_demo=3"))
    with pytest.raises(ConfigError, match="unknown unit 'feasibility/cutt'"):
        run_pipeline(_args(three_demos, out, tiny, "only=feasibility/cutt"))
    with pytest.raises(ConfigError, match="set by the pipeline; use skills="):
        run_pipeline(_args(three_demos, out, tiny, "feasibility.skill=push"))
    with pytest.raises(ConfigError, match="needs a trained VAE"):
        run_pipeline(_args(three_demos, out, tiny, "stages=feasibility", f"feasibility.vae={tmp_path / 'untrained'}"))
    assert not out.exists()


def test_a_root_without_a_vae_trains_feasibility_on_the_shipped_one(tmp_path):
    """`pasta pipeline stages=feasibility,policy skills=NEW out=ROOT`: the root has no VAE and the run trains none,
    so its feasibility encodes with the shipped VAE, as `pasta train feasibility` does (nothing to copy)."""
    from pasta.pipeline import PipelineConfig, plan
    from pasta.pipeline.stages import vae_dir
    from pasta.weights import ROOT

    cfg = PipelineConfig(data=str(tmp_path / "data"), out=str(tmp_path / "models"), stages="feasibility",
                         skills="push")
    (unit,) = plan(cfg, {})
    assert vae_dir(cfg, unit) == ROOT / "vae"
    (tmp_path / "models" / "vae").mkdir(parents=True)  # an untrained folder of the root's own is not a VAE
    assert vae_dir(cfg, unit) == ROOT / "vae"


def test_demos_stage_fills_in_missing_demos_then_skips(tmp_path, monkeypatch):
    """The demos unit with the simulator replaced by synthetic demonstrations."""
    import pasta.demos.generate as generate
    from synthetic_demos import synthetic_demo

    def fake_generate(cfg, *, progress=True, backend=None):
        generate.validate(cfg).mkdir(parents=True, exist_ok=True)  # as generate_demos: the checks create nothing
        todo = generate.pending(cfg)
        for i in todo:
            arrays = synthetic_demo(cfg.skill, seed=i, steps=3, num_points=50)
            np.savez(generate.demo_path(cfg.out, cfg.skill, i), **arrays)
        generate.write_manifest(cfg)
        return {"generated": len(todo), "skipped": cfg.num - len(todo), "wall_s": 0.0, "mean_steps": 3.0}

    monkeypatch.setattr(generate, "generate_demos", fake_generate)
    args = [f"data={tmp_path / 'demos'}", f"out={tmp_path / 'models'}", "stages=demos", "skills=cut", "workers=0",
            "variant_demos=0"]  # the default demos only (the cut's `long` variant unit: the test below)
    assert _status(run_pipeline([*args, "num_demos=2"], echo=lambda _: None)) == {"demos/cut": "ran"}
    assert _status(run_pipeline([*args, "num_demos=2", "workers=2"], echo=lambda _: None)) == {"demos/cut": "skipped"}
    results = run_pipeline([*args, "num_demos=3"], echo=lambda _: None)
    assert _status(results) == {"demos/cut": "ran"} and results[0].metrics["generated"] == 1
    assert len(list((tmp_path / "demos" / "cut").glob("demo_*.npz"))) == 3


def test_command_line(three_demos, tmp_path, tiny, capsys):
    with pytest.raises(SystemExit):
        main(["pipeline", "--help"])
    text = capsys.readouterr().out
    for needle in ("examples:", "only=", "force=true", "<stage>.<key>=value", "feasibility.push.epochs", "make train"):
        assert needle in text
    assert main(["pipeline", *_args(three_demos, tmp_path, tiny, "vae.epoch=1")]) == 2
    assert "did you mean 'epochs'" in capsys.readouterr().err
    assert main(["pipeline", *_args(three_demos, tmp_path, tiny, "stages=vae")]) == 0
    out = capsys.readouterr().out
    assert "[1/1] vae done in" in out and "1 ran, 0 skipped" in out


def test_demos_stage_adds_the_variant_units_the_skills_declare():
    from pasta.pipeline import PipelineConfig, plan

    from pasta.demos import demo_skills

    units = plan(PipelineConfig(stages="demos", num_demos=20), {})
    wide = {u.name: u for u in units}["demos/push-wide"]
    assert {f"demos/{s}" for s in demo_skills()} <= {u.name for u in units}  # one per skill, plus variants
    builtin = [u.name for u in units if u.configs[0].skill in ("cut", "push", "roll")]
    assert builtin == ["demos/cut", "demos/cut-long", "demos/push", "demos/push-wide", "demos/push-nudge", "demos/roll",
                       "demos/roll-board", "demos/roll-sheet"]
    long = {u.name: u for u in units}["demos/cut-long"]
    assert (long.configs[0].num, long.configs[0].scene) == (170, "long")  # 20 default + 150 for the reset pose
    assert (wide.configs[0].num, wide.configs[0].scene, wide.configs[0].skill) == (170, "wide", "push")
    nudge = {u.name: u for u in units}["demos/push-nudge"]  # the indices after the wide ones
    assert (nudge.configs[0].num, nudge.configs[0].scene) == (320, "nudge")
    board = {u.name: u for u in units}["demos/roll-board"]
    assert (board.configs[0].num, board.configs[0].scene) == (120, "board")  # 20 default + 100 on the board
    sheet = {u.name: u for u in units}["demos/roll-sheet"]  # the policy's board cubes rolled into LiftSpread's sheet
    assert (sheet.configs[0].num, sheet.configs[0].scene) == (270, "sheet")
    wide = {u.name: u for u in plan(PipelineConfig(stages="demos", num_demos=20, variant_demos=5), {})}["demos/push-wide"]
    assert wide.configs[0].num == 25
    assert "demos/push-wide" not in [u.name for u in plan(PipelineConfig(stages="demos", variant_demos=0), {})]


def test_per_skill_settings_come_from_the_skill_plugins():
    """The values the shipped models were trained with, now declared by each skill's training_defaults."""
    from pasta.pipeline import PipelineConfig, parse_arguments, plan

    units = {u.name: u for u in plan(PipelineConfig(stages="feasibility,policy"), {})}
    feas = {s: units[f"feasibility/{s}"].configs[1] for s in ("cut", "push", "roll")}
    assert [(f.stride, f.shift_per_positive, f.shift_entities) for f in feas.values()] == [
        (3, 5, "one"), (4, 0, "all"), (4, 5, "all")]
    assert feas["cut"].shift_max == 0.25
    assert [units[f"feasibility/{s}"].configs[0].epochs for s in ("cut", "push", "roll")] == [30, 20, 20]
    pol = {s: units[f"policy/{s}"].configs[1] for s in ("cut", "push", "roll")}
    assert [(p.step_feature, p.pose_feature, p.start_at_reset) for p in pol.values()] == [
        (True, True, True), (True, True, False), (True, True, False)]
    assert units["policy/lift"].configs[1].goal_feature and pol["push"].goal_feature and not pol["cut"].goal_feature
    # skills= restricts; a command-line key still wins over the plugin's default
    units = plan(*parse_arguments(["stages=feasibility", "skills=roll", "feasibility.roll.stride=2"]))
    assert [u.name for u in units] == ["feasibility/roll"] and units[0].configs[1].stride == 2
