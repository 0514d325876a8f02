"""``pasta plan``: point-cloud files in, plan.json and decoded sub-goal clouds out (analytic models)."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from pasta.cli import main
from pasta.commands import plan as plan_cmd
from pasta.core import Plan
from pasta.core.errors import ConfigError, InputError
from pasta.plugins import registry
from pasta.plugins.analytic import AnalyticEncoder, AnalyticPlugin, analytic_problem


@pytest.fixture
def analytic_plugins(monkeypatch):
    plugins = registry.discover(extra={"analytic": AnalyticPlugin()})
    monkeypatch.setattr(registry, "_cache", plugins)
    return plugins


def _clouds(tmp_path):
    p, enc = analytic_problem(), AnalyticEncoder()
    obs = enc.decode(p.obs, 300).reshape(-1, 3).numpy()
    goal = enc.decode(p.goal, 300).reshape(-1, 3).numpy()
    np.save(tmp_path / "obs.npy", obs)
    with open(tmp_path / "goal.ply", "w") as f:  # ASCII PLY with an extra property
        f.write(f"ply\nformat ascii 1.0\nelement vertex {len(goal)}\nproperty float x\nproperty float y\nproperty float z\n"
                "property float intensity\nend_header\n")
        for x, y, z in goal:
            f.write(f"{x:.7f} {y:.7f} {z:.7f} 1.0\n")
    return tmp_path / "obs.npy", tmp_path / "goal.ply"


ARGS = ["encoder=analytic", "cost_model=analytic", "skills=split,move,flatten", "num_points=300", "min_points=20",
        "planner.num_samples=128", "planner.iterations=100"]


def test_plan_from_files(tmp_path, analytic_plugins, capsys):
    obs, goal = _clouds(tmp_path)
    out = tmp_path / "out"
    assert main(["plan", f"obs={obs}", f"goal={goal}", f"out={out}", *ARGS]) == 0
    plan = Plan.from_json((out / "plan.json").read_text())
    assert plan.skills == ("split", "move", "flatten") and plan.score > 0.5
    assert plan.planner == "exhaustive"
    shapes = [np.load(out / f"step_{h}_subgoal.npy").shape for h in range(3)]
    assert shapes == [(2, 300, 3), (1, 300, 3), (1, 300, 3)]
    assert json.loads((out / "entities.json").read_text())["goal"] == 2
    assert "plan by exhaustive" in capsys.readouterr().out


def test_planner_switch_and_determinism(tmp_path, analytic_plugins):
    obs, goal = _clouds(tmp_path)
    texts = []
    for run in range(2):
        out = tmp_path / f"o{run}"
        assert main(["plan", f"obs={obs}", f"goal={goal}", f"out={out}", *ARGS, "planner=sampling", "planner.num_samples=64",
                     "planner.iterations=10"]) == 0
        texts.append(Plan.from_json((out / "plan.json").read_text()).to_json(timings=False))
    assert texts[0] == texts[1] and '"planner": "sampling"' in texts[0]


def test_bad_files(tmp_path, analytic_plugins, capsys):
    obs, goal = _clouds(tmp_path)
    np.save(tmp_path / "flat.npy", np.zeros((10, 2)))
    nan = np.load(obs)
    nan[3, 1] = np.nan
    np.save(tmp_path / "nan.npy", nan)
    (tmp_path / "bad.ply").write_text("ply\nformat binary_little_endian 1.0\nend_header\n")
    for bad, message in [(tmp_path / "missing.npy", "does not exist"), (tmp_path / "flat.npy", "shape (P, 3)"),
                         (tmp_path / "nan.npy", "NaN"), (tmp_path / "bad.ply", "only ASCII PLY")]:
        assert main(["plan", f"obs={bad}", f"goal={goal}", f"out={tmp_path / 'x'}", *ARGS]) == 2
        assert message in capsys.readouterr().err
    with pytest.raises(ConfigError, match="obs=FILE"):
        plan_cmd.split_arguments([f"goal={goal}"])
    with pytest.raises(InputError):
        plan_cmd.load_cloud(tmp_path / "obs.txt")


def test_impossible_goal_is_a_clear_error(tmp_path, analytic_plugins, capsys):
    obs, goal = _clouds(tmp_path)
    assert main(["plan", f"obs={obs}", f"goal={goal}", f"out={tmp_path / 'x'}", *ARGS, "horizon=1", "skills=move,flatten"]) == 2
    assert "2 goal entities" in capsys.readouterr().err


def test_skill_choice_is_the_same_rule_as_run(tmp_path, analytic_plugins, monkeypatch, capsys):
    """Without skills=, skills lacking trained weights are left out with one warning line (the shipped root
    here is empty, so cut, push and roll go; the analytic skills compute their own feasibility)."""
    import pasta.weights

    obs, goal = _clouds(tmp_path)
    monkeypatch.setattr(pasta.weights, "ROOT", tmp_path / "no_weights")
    args = [a for a in ARGS if not a.startswith("skills=")]
    assert main(["plan", f"obs={obs}", f"goal={goal}", f"out={tmp_path / 'o'}", *args]) == 0
    err = [line for line in capsys.readouterr().err.splitlines() if line.startswith("warning: skills")]
    assert len(err) == 1 and "left out: cut, push, roll" in err[0] and "pasta train feasibility" in err[0]
    assert Plan.from_json((tmp_path / "o" / "plan.json").read_text()).skills == ("split", "move", "flatten")
    assert main(["plan", f"obs={obs}", f"goal={goal}", f"out={tmp_path / 'x'}", *args, "skills=split,move,cut"]) == 2
    assert "skill 'cut' has no feasibility network" in capsys.readouterr().err
    assert main(["plan", f"obs={obs}", f"goal={goal}", f"out={tmp_path / 'x'}", *args, "skills=split,mvoe"]) == 2
    assert "unknown skill 'mvoe'; did you mean 'move'?" in capsys.readouterr().err
    assert main(["plan", f"obs={obs}", f"goal={goal}", f"out={tmp_path / 'x'}", *args, "skeleton=cut,move,flatten"]) == 2
    assert "skeleton= needs the skills cut, move, flatten; left out: 'cut': feasibility network" in capsys.readouterr().err
