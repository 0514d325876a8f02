"""`pasta eval` and the shared episode session: method resolution, shipped weights, resumable results."""

import argparse
import json
from pathlib import Path

import pytest

from pasta.core.errors import ConfigError
from pasta.config.run import METHODS
from pasta.execute.session import EpisodeOutcome, build_session
from pasta.weights import ROOT, models_root, shipped


def test_shipped_weights_cover_every_module_the_default_pipeline_loads():
    have = set(shipped())
    assert {"vae", "cost", "feasibility/cut", "feasibility/push", "feasibility/roll"} <= have
    for rel in have:
        assert (ROOT / rel / "model.json").exists() and (ROOT / rel / "metrics.json").exists()
        assert not (ROOT / rel / "last.safetensors").exists()  # resume checkpoints are not shipped
    assert models_root(None) == ROOT and models_root(ROOT / "ablations") == ROOT / "ablations"


def test_session_loads_the_shipped_weights_by_default():
    session = build_session("crs", method="pasta")
    assert session.models == ROOT
    assert session.cfg.planner.name == "exhaustive" and session.exe.controller == "heuristic"
    assert session.encoder.latent_dim > 3
    assert all(s.feasibility_model is not None for s in session.skills)
    twice = build_session("crs_twice")  # the task asks for the paper's planner and its skeleton given
    assert twice.cfg.planner.name == "receding_horizon" and twice.cfg.skeleton == "task"
    inst = type("Instance", (), {"skeleton": ["cut", "cut", "push", "push", "roll", "roll"]})()
    assert twice.skeleton(inst) == tuple(inst.skeleton) and session.skeleton(inst) is None
    searched = build_session("crs_twice", planner="prefix_beam", skeleton="")  # the command line wins
    assert searched.cfg.planner.name == "prefix_beam" and searched.skeleton(inst) is None
    assert build_session("crs", planner="sampling").cfg.planner.name == "sampling"


def test_the_shipped_flat_baseline_loads_by_default():
    from pasta.nn.flat import FlatSkill

    session = build_session("crs", method="flat")  # the README's Flat 3D row: pasta/weights/flat
    assert session.models == ROOT and session.encoder.scope == "scene"
    assert [s.name for s in session.skills] == ["cut", "push", "roll"]
    assert all(isinstance(s, FlatSkill) and (s.n_in, s.n_out) == (1, 1) for s in session.skills)
    assert all(s.feasibility_model is not None for s in session.skills)


def test_the_no_hard_negatives_root_is_the_shipped_weights_but_its_feasibility_networks():
    nohn = ROOT / "ablations" / "no_hard_negatives"
    # the VAE and cost are links to the shipped ones, so the networks' latent space is the one they were trained on
    for module in ("vae", "cost"):
        assert (nohn / module).resolve() == (ROOT / module).resolve()
    assert sorted(p.name for p in nohn.iterdir()) == ["cost", "feasibility", "vae"]
    assert sorted(p.name for p in (nohn / "feasibility").iterdir()) == ["cut", "push"]
    session = build_session("cut_rearrange", models=str(nohn), skills="cut,push")
    assert session.models == nohn and [s.name for s in session.skills] == ["cut", "push"]
    assert session.feasibility_training() == {s: {"hard_per_positive": 0, "shift_per_positive": 0} for s in ("cut", "push")}
    assert build_session("cut_rearrange", skills="cut,push").feasibility_training()["cut"]["hard_per_positive"] > 0


def test_session_rejects_unknown_method_task_and_skeleton():
    with pytest.raises(ConfigError, match="method=pastaa: must be one of " + ", ".join(METHODS) + "; did you mean 'pasta'"):
        build_session("crs", method="pastaa")
    with pytest.raises(Exception, match="did you mean 'crs'"):
        build_session("crss")
    with pytest.raises(ConfigError, match="skeleton=maybe: 'maybe' is not a registered skill"):
        build_session("crs", method="oracle", skeleton="maybe")


def test_session_skills_choose_the_set_and_the_task_chain_must_fit(tmp_path, capsys):
    from pasta.commands.run import print_skill_warning

    session = build_session("crs", skills="cut,push,roll")
    assert [s.name for s in session.skills] == ["cut", "push", "roll"] and session.describe()["skills"] == ["cut", "push", "roll"]
    with pytest.raises(ConfigError, match=r"task 'crs' \(its ground-truth chain\) needs the skills cut, push, roll; "
                                          r"left out: 'roll': not in skills="):
        build_session("crs", skills="cut,push")
    from pasta.plugins import get_plugins

    known = get_plugins().skills.names()  # every registered skill, the built-ins among them
    assert {"cut", "push", "roll"} <= set(known)
    with pytest.raises(ConfigError, match=f"'pusj' is not a registered skill; did you mean 'push'.*registered skills: "
                                          f"{', '.join(known)}$"):
        build_session("crs", skills="cut,pusj,roll")
    # a models root of its own (its own VAE, so nothing shipped is borrowed) where roll has no feasibility network:
    # left out with one warning line, so crs cannot run
    for rel in ("vae", "feasibility/cut", "feasibility/push"):
        (tmp_path / rel).mkdir(parents=True)
        (tmp_path / rel / "model.safetensors").write_text("")
        (tmp_path / rel / "model.json").write_text("")
    with pytest.raises(ConfigError, match=r"left out: 'roll': feasibility network .*pasta train feasibility"):
        build_session("crs", models=str(tmp_path))
    oracle = build_session("crs", method="oracle", skills="cut")  # the oracle plans nothing: skills= is not used
    print_skill_warning(oracle)
    assert capsys.readouterr().err == ""


class _FakeSession:
    def __init__(self, task, overrides=()):
        from pasta.config import load_config

        self.task, self.method = task, "pasta"
        self.cfg = load_config([f"task={task.name}", *overrides])
        self.skill_choice = None
        self.calls = []

    def describe(self):
        return {"task": self.task.name, "method": "pasta", "planner": "exhaustive", "controller": "heuristic",
                "skills": [], "config": {"seed": 0, "planner": "exhaustive"}}

    def episode(self, seed, sim=None):
        self.calls.append(seed)
        return EpisodeOutcome(self.task.name, "pasta", seed, improvement=0.5 + (seed % 2) * 0.4, success=bool(seed % 2))


def test_eval_writes_one_line_per_episode_and_resumes(tmp_path, monkeypatch):
    from pasta.commands import eval as eval_cmd
    from pasta.tasks import get_task

    task = get_task("crs")
    task.make_sim = lambda: None  # no simulator needed by the fake session
    fake = _FakeSession(task)
    monkeypatch.setattr("pasta.execute.session.build_session", lambda *a, **k: fake)
    args = argparse.Namespace(overrides=["task=crs", "num=3", f"out={tmp_path}"])
    assert eval_cmd.run(args) == 0
    lines = (tmp_path / "crs_pasta.jsonl").read_text().splitlines()
    assert [json.loads(x)["seed"] for x in lines] == [1000, 1001, 1002]
    summary = json.loads((tmp_path / "crs_pasta.json").read_text())
    assert summary["episodes"] == 3 and summary["success_rate"] == pytest.approx(1 / 3)
    assert summary["improvement_mean"] == pytest.approx((0.5 + 0.9 + 0.5) / 3)
    fake.calls.clear()  # a larger num runs only the new seeds
    assert eval_cmd.run(argparse.Namespace(overrides=["task=crs", "num=4", f"out={tmp_path}"])) == 0
    assert fake.calls == [1003]
    with pytest.raises(ConfigError, match="fixed test seeds"):
        eval_cmd.run(argparse.Namespace(overrides=["task=crs", "seed=3", f"out={tmp_path}"]))
    with pytest.raises(ConfigError, match="did you mean 'num'"):
        eval_cmd.run(argparse.Namespace(overrides=["task=crs", "nmu=3", f"out={tmp_path}"]))


def test_eval_validation_split_runs_its_own_seeds_into_its_own_file(tmp_path, monkeypatch):
    from pasta.commands import eval as eval_cmd
    from pasta.tasks import fixed_test_seeds, fixed_val_seeds, get_task

    assert not set(fixed_val_seeds(20)) & set(fixed_test_seeds(20))
    task = get_task("crs")
    task.make_sim = lambda: None
    fake = _FakeSession(task)
    monkeypatch.setattr("pasta.execute.session.build_session", lambda *a, **k: fake)
    assert eval_cmd.run(argparse.Namespace(overrides=["task=crs", "num=2", "split=val", f"out={tmp_path}"])) == 0
    assert fake.calls == [2000, 2001]
    assert not (tmp_path / "crs_pasta.jsonl").exists()
    assert json.loads((tmp_path / "crs_pasta_val.json").read_text())["split"] == "val"
    with pytest.raises(ConfigError, match="split=train: must be one of test, val"):
        eval_cmd.run(argparse.Namespace(overrides=["task=crs", "split=train", f"out={tmp_path}"]))


def test_result_rows_record_the_weights_they_were_made_with(tmp_path):
    import hashlib

    from pasta.io.checkpoint import weights_digest

    session = build_session("cut_rearrange", skills="cut,push")
    weights = session.describe()["weights"]
    assert set(weights) == {"encoder", "cost", "feasibility/cut", "feasibility/push"}
    cost_file = Path(session.cfg.cost_model.weights) / "model.safetensors"
    assert weights["cost"] == hashlib.sha256(cost_file.read_bytes()).hexdigest()[:16]
    assert weights_digest(tmp_path) == ""  # no checkpoint there
