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
from pasta.testing import AnalyticEncoder, AnalyticPlugin, analytic_problem


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


ARGS = ["encoder=analytic", "cost_model=analytic", "skills=split,move,flatten", "perception.num_points=300",
        "perception.min_points=20",
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
    text = capsys.readouterr().out
    assert "plan by exhaustive" in text
    # scene=auto (the default): the analytic pieces float 3 cm above the floor, read as resting on a surface
    assert "scene: scene=auto (detected from the clouds: pieces resting above the floor)" in text
    scene = plan.info["scene"]
    assert scene["static"] == [] and scene["surfaces"][0] == 0.02 and len(scene["surfaces"]) > 1
    assert scene["left_out"] == {}  # skills= names the skills: only those are fitted


def test_planner_switch_and_determinism(tmp_path, analytic_plugins):
    obs, goal = _clouds(tmp_path)
    texts = []
    for run in range(2):
        out = tmp_path / f"o{run}"
        assert main(["plan", f"obs={obs}", f"goal={goal}", f"out={out}", *ARGS, "planner=sampling", "planner.num_samples=64",
                     "planner.iterations=10"]) in (0, 3)  # 10 iterations: flagged unreachable (exit 3)
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
                         (tmp_path / "nan.npy", "NaN"), (tmp_path / "bad.ply", "vertex properties x, y, z")]:
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
    assert len(err) == 1 and "pasta train feasibility" in err[0]
    left_out = set(err[0].split("left out: ")[1].split(" (")[0].split(", "))
    assert {"cut", "push", "roll"} <= left_out and not left_out & {"split", "move", "flatten"}  # other built-ins may come
    assert Plan.from_json((tmp_path / "o" / "plan.json").read_text()).skills == ("split", "move", "flatten")
    assert main(["plan", f"obs={obs}", f"goal={goal}", f"out={tmp_path / 'x'}", *args, "skills=split,move,cut"]) == 2
    assert "skill 'cut' has no feasibility network" in capsys.readouterr().err
    assert main(["plan", f"obs={obs}", f"goal={goal}", f"out={tmp_path / 'x'}", *args, "skills=split,mvoe"]) == 2
    assert "skills=split,mvoe: 'mvoe' is not a registered skill; did you mean 'move'?" in capsys.readouterr().err
    assert main(["plan", f"obs={obs}", f"goal={goal}", f"out={tmp_path / 'x'}", *args, "skeleton=cut,move,flatten"]) == 2
    assert "skeleton= needs the skills cut, move, flatten; left out: 'cut': feasibility network" in capsys.readouterr().err


# -- hardening (issue 21) -------------------------------------------------------------------------------


def test_output_path_is_checked_before_anything_is_computed(tmp_path, analytic_plugins, monkeypatch, capsys):
    import pasta.config

    obs, goal = _clouds(tmp_path)
    (tmp_path / "taken").write_text("not a directory")
    monkeypatch.setattr(pasta.config, "load_config", lambda *a, **k: pytest.fail("computed before out= was checked"))
    for out, message in [(tmp_path / "taken", "exists and is not a directory"),
                         (tmp_path / "taken" / "sub", "is a file, so the path cannot be created")]:
        assert main(["plan", f"obs={tmp_path / 'missing.npy'}", f"goal={goal}", f"out={out}", *ARGS]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and err.startswith("pasta plan: error: out=") and message in err
    assert (tmp_path / "taken").read_text() == "not a directory"


@pytest.mark.parametrize("item, message", [
    ("threads=abc", "threads=abc: must be an integer"), ("threads=-1", "threads=-1: must be an integer in [0, 1024]"),
    ("horizon=11", "horizon=11: must be an integer in [1, 10]"),
    ("perception.num_points=8", "perception.num_points=8: must be an integer in [16, 10000]"),
    ("perception.min_points=0", "perception.min_points=0: must be"),
    ("perception.max_points=10", "perception.max_points=10: must be >= perception.min_points (20)"),
])
def test_command_keys_are_range_checked(tmp_path, analytic_plugins, capsys, item, message):
    obs, goal = _clouds(tmp_path)
    assert main(["plan", f"obs={obs}", f"goal={goal}", f"out={tmp_path / 'o'}", *ARGS, item]) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_threads_pin_torch(tmp_path, analytic_plugins):
    obs, goal = _clouds(tmp_path)
    before = torch.get_num_threads()
    try:
        torch.set_num_threads(2)
        assert main(["plan", f"obs={obs}", f"goal={goal}", f"out={tmp_path / 'o'}", *ARGS, "planner.iterations=3"]) in (0, 3)
        assert torch.get_num_threads() == 1  # the default, as in `pasta run`
    finally:
        torch.set_num_threads(before)


def test_plan_runs_on_the_cpu_only():
    from omegaconf import OmegaConf

    plan_cmd.check_cpu_only(OmegaConf.create({"device": "cpu", "encoder": {"device": "cpu"}, "planner": {}}))
    for cfg, key in [({"device": "cuda"}, "device=cuda"), ({"device": "cpu", "cost_model": {"device": "cuda:0"}},
                                                           "cost_model.device=cuda:0")]:
        with pytest.raises(ConfigError, match=f"{key}: pasta plan runs on the CPU.*allowed: cpu"):
            plan_cmd.check_cpu_only(OmegaConf.create(cfg))


def test_clouds_outside_the_workspace_or_too_small_are_input_errors(tmp_path, analytic_plugins, capsys):
    obs, goal = _clouds(tmp_path)
    pts = np.load(obs)
    np.save(tmp_path / "far.npy", pts + 100.0)
    np.save(tmp_path / "few.npy", pts[:5])
    for bad, message in [(tmp_path / "far.npy", "300 of 300 points lie outside the workspace, the unit cube [0, 1]^3"),
                         (tmp_path / "few.npy", "obs cloud has 5 point(s); a cloud needs at least min_points=20")]:
        assert main(["plan", f"obs={bad}", f"goal={goal}", f"out={tmp_path / 'o'}", *ARGS]) == 2
        assert message in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_large_clouds_are_voxel_downsampled_with_a_note(tmp_path, analytic_plugins, capsys):
    obs, goal = _clouds(tmp_path)
    rng = np.random.default_rng(0)
    pts = np.load(obs)
    dense = np.clip(pts[rng.integers(0, len(pts), 40_000)] + rng.normal(0, 0.003, (40_000, 3)), 0, 1)
    np.save(tmp_path / "dense.npy", dense.astype(np.float32))
    out = tmp_path / "o"
    assert main(["plan", f"obs={tmp_path / 'dense.npy'}", f"goal={goal}", f"out={out}", *ARGS,
                 "perception.max_points=3000"]) == 0
    err = capsys.readouterr().err
    assert "note: obs cloud has 40,000 points, more than perception.max_points=3,000: voxel-downsampled" in err
    assert "goal cloud" not in err  # 600 points: untouched
    assert Plan.from_json((out / "plan.json").read_text()).skills == ("split", "move", "flatten")


def test_refused_file_sizes_are_not_read(tmp_path, monkeypatch):
    obs, _ = _clouds(tmp_path)
    monkeypatch.setattr(plan_cmd, "MAX_FILE_POINTS", 100)
    with pytest.raises(InputError, match="has 300 points, more than pasta plan reads"):
        plan_cmd.load_cloud(obs, "obs")


def test_nan_latents_and_plans_never_reach_a_file(tmp_path, analytic_plugins, monkeypatch, capsys):
    import dataclasses

    obs, goal = _clouds(tmp_path)
    real_create = analytic_plugins.planners.create

    class NanPlanner:
        def __init__(self, inner):
            self.inner = inner

        def plan(self, problem):
            return dataclasses.replace(self.inner.plan(problem), score=float("nan"))

    monkeypatch.setattr(analytic_plugins.planners, "create", lambda *a, **k: NanPlanner(real_create(*a, **k)))
    out = tmp_path / "o"
    assert main(["plan", f"obs={obs}", f"goal={goal}", f"out={out}", *ARGS, "planner.iterations=3"]) == 2
    assert "plan by 'exhaustive' is not valid: score is nan" in capsys.readouterr().err
    assert not out.exists()
    monkeypatch.setattr(analytic_plugins.planners, "create", real_create)
    monkeypatch.setattr(AnalyticEncoder, "encode", lambda self, pts: torch.full((len(pts), 5), float("nan")))
    assert main(["plan", f"obs={obs}", f"goal={goal}", f"out={out}", *ARGS]) == 2
    assert "encoded obs entities (encoder 'analytic') contains NaN" in capsys.readouterr().err
    assert not out.exists()


# -- real-world inputs (issue 20): frames, organised clouds, preprocessing, labels, checks, exit codes --------


def test_frames_labels_and_subgoals_in_the_input_frame(tmp_path, analytic_plugins):
    """The same clouds in millimetres and z up, one organised with holes, plan exactly as in metres; the
    sub-goals come back in millimetres and z up, the labels shaped like the input with -1 at the holes."""
    from pasta.perception import CloudFrame

    obs, goal = _clouds(tmp_path)
    ref = tmp_path / "ref"
    assert main(["plan", f"obs={obs}", f"goal={goal}", f"out={ref}", *ARGS]) == 0
    frame = CloudFrame(units="mm", up="z")
    pts = np.load(obs).astype(np.float64)
    grid = np.full((20, 16, 3), np.nan)  # 320 pixels, 300 points, 20 holes
    grid.reshape(-1, 3)[:300] = frame.from_workspace(pts)
    grid.reshape(-1, 3)[300:310] = 0.0
    np.save(tmp_path / "obs_mm.npy", grid)
    np.save(tmp_path / "goal_mm.npy", frame.from_workspace(plan_cmd.load_cloud(goal)))
    out = tmp_path / "mm"
    assert main(["plan", f"obs={tmp_path / 'obs_mm.npy'}", f"goal={tmp_path / 'goal_mm.npy'}", f"out={out}", *ARGS,
                 "units=mm", "up=z"]) == 0
    a, b = Plan.from_json((ref / "plan.json").read_text()), Plan.from_json((out / "plan.json").read_text())
    assert a.skills == b.skills and [s.inputs for s in a.steps] == [s.inputs for s in b.steps]
    assert abs(a.score - b.score) < 1e-3
    for h in range(3):
        ws = np.load(out / f"step_{h}_subgoal.npy")
        np.testing.assert_allclose(np.load(out / f"step_{h}_subgoal_input.npy"), frame.from_workspace(ws), rtol=1e-5)
    labels = np.load(out / "obs_labels.npy")
    assert labels.shape == (20, 16) and (labels.reshape(-1)[300:] == -1).all()
    np.testing.assert_array_equal(labels.reshape(-1)[:300], np.load(ref / "obs_labels.npy"))
    assert sorted(set(np.load(ref / "goal_labels.npy").tolist())) == [0, 1]
    assert not (ref / "step_0_subgoal_input.npy").exists()  # metres, y up: the workspace files are the input's
    info = json.loads((out / "plan.json").read_text())["info"]
    assert info["input"]["frame"]["units"] == "mm" and info["confidence"]["steps"][0]["skill"] == "split"


def test_preprocessing_drops_outliers_and_a_table(tmp_path, analytic_plugins, capsys):
    obs, goal = _clouds(tmp_path)
    rng = np.random.default_rng(0)
    pts = np.load(obs)
    table = np.column_stack([rng.uniform(0, 1, 3000), np.full(3000, 0.0), rng.uniform(0, 1, 3000)])
    noisy = np.concatenate([pts, table, rng.uniform(0.2, 0.8, (6, 3))]).astype(np.float32)
    np.save(tmp_path / "noisy.npy", noisy)
    args = ["plan", f"obs={tmp_path / 'noisy.npy'}", f"goal={goal}", *ARGS]
    assert main([*args, f"out={tmp_path / 'raw'}"]) in (2, 3)  # the table joins the pieces into one entity
    capsys.readouterr()
    assert main([*args, f"out={tmp_path / 'pre'}", "preprocess.table=height", "preprocess.table_height=0.0",
                 "preprocess.table_margin=0.001", "preprocess.outliers=statistical"]) == 0
    err = capsys.readouterr().err
    assert "note: obs cloud preprocessed: 3,306 points, " in err and " on the table, 6 outliers, " in err
    labels = np.load(tmp_path / "pre" / "obs_labels.npy")
    assert (labels[len(pts):] == -1).all() and (labels[:len(pts)] >= 0).mean() > 0.95
    assert Plan.from_json((tmp_path / "pre" / "plan.json").read_text()).skills == ("split", "move", "flatten")


def test_contract_checks_and_exit_codes(tmp_path, analytic_plugins, capsys):
    obs, goal = _clouds(tmp_path)
    raised = plan_cmd.load_cloud(obs) + np.float32([0, 0.5, 0])  # inside the cube, above the training box
    np.save(tmp_path / "high.npy", raised)
    assert main(["plan", f"obs={tmp_path / 'high.npy'}", f"goal={goal}", f"out={tmp_path / 'h'}", *ARGS]) == 2
    err = capsys.readouterr().err
    assert "outside the box the models were trained on" in err and "out in y" in err
    assert not (tmp_path / "h" / "plan.json").exists()
    # a feasibility bar no plan can pass: the plan is written, flagged, and the exit code is 3
    out = tmp_path / "u"
    assert main(["plan", f"obs={obs}", f"goal={goal}", f"out={out}", *ARGS, "check.min_feasibility=1.0"]) == 3
    assert "warning: unreachable: predicted feasibility below check.min_feasibility=1" in capsys.readouterr().err
    flags = json.loads((out / "plan.json").read_text())["info"]["flags"]
    assert [f["kind"] for f in flags] == ["unreachable"]
    for bad, message in [("units=cm", "units=cm: must be one of m, mm"), ("up=x", "up=x"),
                         ("perception.eps=0", "perception.eps=0"), ("preprocess=kinect", "preprocess=kinect"),
                         ("preprocess.table=plane", "preprocess.table=plane"), (f"transform={obs}", "4x4"),
                         ("preprocess.crop_low=0,0", "three comma-separated"),
                         ("preprocess.crop_high=0,0,0", "low < high")]:
        assert main(["plan", f"obs={obs}", f"goal={goal}", f"out={tmp_path / 'x'}", *ARGS, bad]) == 2
        assert message in capsys.readouterr().err


def test_decompose_keys_reach_dbscan(tmp_path, analytic_plugins):
    obs, goal = _clouds(tmp_path)
    out = tmp_path / "o"
    # a radius that spans the whole scene merges the goal's two pieces: a plan far from the real goal (their
    # merged hull is 3.7 times the observed volume: let it through check.volume_ratio to see the plan's flag)
    assert main(["plan", f"obs={obs}", f"goal={goal}", f"out={out}", *ARGS, "perception.eps=0.9",
                 "check.volume_ratio=5"]) == 3
    assert json.loads((out / "entities.json").read_text())["goal"] == 1  # planned 1 -> 1, flagged unreachable
    assert main(["plan", f"obs={obs}", f"goal={goal}", f"out={out}", *ARGS, "perception.min_samples=3"]) == 0
    assert json.loads((out / "plan.json").read_text())["info"]["input"]["decompose"]["min_samples"] == 3


def test_plan_never_writes_through_a_link_planted_in_out(tmp_path, analytic_plugins):
    """Links at every file name `pasta plan` writes (and at their temporary names) point outside out=: the
    plan is written, the files outside are untouched, and every output is a regular file (issue 41)."""
    from output_links import assert_regular, assert_untouched, plant_links, written_files

    p, enc = analytic_problem(), AnalyticEncoder()
    obs, goal = tmp_path / "obs_mm.npy", tmp_path / "goal_mm.npy"  # millimetres: sub-goals are also written in them
    np.save(obs, 1000 * enc.decode(p.obs, 300).reshape(-1, 3).numpy())
    np.save(goal, 1000 * enc.decode(p.goal, 300).reshape(-1, 3).numpy())
    first = tmp_path / "first"
    assert main(["plan", f"obs={obs}", f"goal={goal}", f"out={first}", *ARGS, "units=mm"]) == 0
    names = written_files(first)
    assert {"plan.json", "entities.json", "obs_labels.npy", "goal_labels.npy", "step_0_subgoal.npy",
            "step_0_subgoal_input.npy"} <= set(names)
    out = tmp_path / "out"
    planted = plant_links(out, names, tmp_path / "victims")
    assert main(["plan", f"obs={obs}", f"goal={goal}", f"out={out}", *ARGS, "units=mm"]) == 0
    assert_untouched(planted)
    assert_regular(out, names)
    again, before = (Plan.from_json((d / "plan.json").read_text()) for d in (out, first))
    assert again.skills == before.skills and again.score == before.score


def test_misleading_cloud_file_messages_name_the_real_problem(tmp_path, analytic_plugins, capsys):
    """Random bytes in a .npy are not "pickled data"; a directory is not "missing" (issue 41)."""
    obs, goal = _clouds(tmp_path)
    noise = tmp_path / "noise.npy"
    noise.write_bytes(np.random.default_rng(0).bytes(4096))
    (tmp_path / "a_dir.npy").mkdir()
    for bad, message in [(noise, "is not a .npy file (it does not start with the NumPy magic bytes"),
                         (tmp_path / "a_dir.npy", "is a directory; give a file")]:
        assert main(["plan", f"obs={bad}", f"goal={goal}", f"out={tmp_path / 'o'}", *ARGS]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and message in err[0] and "pickled" not in err[0], err
    pickled = tmp_path / "objects.npy"
    np.save(pickled, np.array([{"a": 1}], dtype=object), allow_pickle=True)
    assert main(["plan", f"obs={pickled}", f"goal={goal}", f"out={tmp_path / 'o'}", *ARGS]) == 2
    assert "pickle" in capsys.readouterr().err  # a real object array is still named as one
