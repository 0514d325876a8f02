"""Flat 3D baseline: 1 -> 1 skills delegating to the wrapped ones, flat training and :func:`load_flat`."""

import json

import numpy as np
import pytest
import torch

from pasta.core import MissingComponentError
from pasta.core.skill import Controller, Skill, SkillSpec, ToolPose
from pasta.io.checkpoint import IncompatibleCheckpointError, load_checkpoint
from pasta.nn.flat import FlatSkill, flat_skills, load_flat
from pasta.demos.data import load_demo
from pasta.train.run import train
from synthetic_demos import write_synthetic_dataset

TINY = {
    "vae": {"epochs": "1", "width": "16", "fold_hidden": "16", "input_points": "64", "target_points": "64",
            "emd_points": "16", "num_points": "128", "stride": "2", "progress": "false", "batch_size": "8", "threads": "1"},
    "feasibility": {"epochs": "2", "hidden": "16", "num_points": "128", "match_points": "64", "progress": "false",
                    "threads": "1"},
    "cost": {"epochs": "2", "hidden": "16", "num_points": "128", "label_points": "64", "pairs_per_entity": "4",
             "stride": "2", "progress": "false", "threads": "1"},
}


class _Stop(Controller):
    def act(self, obs):
        return np.zeros(2, np.float32), True


class _Split(Skill):
    spec = SkillSpec("split", 1, 2, "knife", "test skill")

    def __init__(self):
        super().__init__({"k": 1})
        self.ctrl = _Stop()

    @property
    def max_steps(self):
        return 7

    def approach_pose(self, piece, goal=None, scene=None):
        return ToolPose((float(len(piece)), 0.0, 0.0))

    def park_pose(self):
        return ToolPose((1.0, 2.0, 3.0))

    def controller(self):
        return self.ctrl

    def expert(self, params):
        return self.ctrl


class _Policy:
    def controller(self, skill):
        return ("policy of", skill.name, skill.n_out)


def test_flat_skills_are_one_to_one_and_delegate():
    base = _Split()
    (flat,) = flat_skills([base])
    assert isinstance(flat, FlatSkill) and isinstance(flat, Skill)
    assert (flat.name, flat.tool, flat.n_in, flat.n_out) == ("split", "knife", 1, 1)
    assert (base.n_in, base.n_out) == (1, 2)  # the wrapped skill is untouched
    assert flat.approach_pose(np.zeros((5, 3))) == ToolPose((5.0, 0.0, 0.0))
    assert flat.park_pose() == base.park_pose()
    assert flat.controller() is base.ctrl and flat.expert({}) is base.ctrl
    assert flat.max_steps == 7 and flat.config == {"k": 1}
    flat.attach_policy(_Policy())
    assert base.policy_model is flat.policy_model is not None
    assert flat.policy() == ("policy of", "split", 2)  # the wrapped skill drives the tool
    with pytest.raises(MissingComponentError, match="feasibility"):
        flat.feasibility(torch.zeros(1, 1, 5), torch.zeros(1, 1, 5))
    flat.attach_feasibility(lambda a, b: torch.full((len(a),), 0.5))
    assert base.feasibility_model is None
    assert flat_skills(flat_skills([base]))[0].wrapped is base
    with pytest.raises(AttributeError):
        flat.no_such_attribute


@pytest.fixture(scope="module")
def flat_root(tmp_path_factory):
    """Tiny synthetic cut demos (with a final_dough) and the three Flat 3D modules trained on them."""
    data = write_synthetic_dataset(tmp_path_factory.mktemp("demos"), per_skill=3, skills=("cut",), steps=4, num_points=300)
    for path in sorted((data / "cut").glob("demo_*.npz")):
        with np.load(path, allow_pickle=False) as f:
            arrays = {k: f[k] for k in f.files}
        np.savez_compressed(path, **arrays, final_dough=arrays["dough"][-1] + np.float32(0.001))
    root = tmp_path_factory.mktemp("models") / "flat"
    figures = {
        "vae": train("vae", data, root, {**TINY["vae"], "flat": "true"}),
        "feasibility": train("feasibility", data, root, {**TINY["feasibility"], "flat": "true", "skill": "cut"}),
        "cost": train("cost", data, root, {**TINY["cost"], "flat": "true"}),
    }
    return data, root, figures


def test_flat_training_writes_the_layout(flat_root):
    data, root, figures = flat_root
    assert load_demo(data / "cut" / "demo_00000.npz").final_dough.shape == (300, 3)
    for sub in ("vae", "feasibility/cut", "cost"):
        assert (root / sub / "model.safetensors").is_file() and (root / sub / "metrics.json").is_file()
    assert figures["vae"]["heldout_examples"] == 4  # one held-out demo: states 0, 2, 4 and its final dough
    assert figures["feasibility"]["train_positives"] == 2 and figures["feasibility"]["heldout_positives"] == 1
    assert 0.0 <= figures["feasibility"]["heldout_auc_hard"] <= 1.0
    assert -1.0 <= figures["cost"]["heldout_spearman"] <= 1.0
    feas = load_checkpoint(root / "feasibility" / "cut", module="feasibility").config
    assert (feas["n_in"], feas["n_out"], feas["scope"], feas["train"]["flat"]) == (1, 1, "scene", True)
    assert load_checkpoint(root / "cost", module="set_cost").config["scope"] == "scene"
    assert json.loads((root / "vae" / "model.json").read_text())["config"]["scope"] == "scene"


def test_load_flat_gives_a_scene_encoder_and_flat_feasibility(flat_root):
    from pasta.plugins import get_plugins

    data, root, _ = flat_root
    cut = get_plugins().skills.create("cut")
    encoder, cost, (flat_cut,) = load_flat(root, [cut])
    assert encoder.scope == "scene" and cut.feasibility_model is None
    dough = load_demo(data / "cut" / "demo_00001.npz")
    u_in = encoder.encode(torch.from_numpy(dough.dough[:1]))[None]  # (1, 1, D)
    u_out = encoder.encode(torch.from_numpy(dough.after[None]))[None]
    u_in, u_out = u_in.repeat(3, 1, 1), u_out.repeat(3, 1, 1) + torch.linspace(0, 0.1, 3)[:, None, None]
    f = flat_cut.feasibility(u_in, u_out)
    assert f.shape == (3,) and bool(((f >= 0) & (f <= 1)).all())
    assert flat_cut.log_feasibility(u_in, u_out).shape == (3,)
    assert cost.set_cost(u_in, u_out).shape == (3,)


def test_missing_flat_weights_name_the_command(flat_root, tmp_path):
    from pasta.plugins import get_plugins

    _, root, _ = flat_root
    push = get_plugins().skills.create("push")
    with pytest.raises(MissingComponentError, match=r"pasta train feasibility data=DIR out=\S+ flat=true skill=push"):
        load_flat(root, [push])
    with pytest.raises(MissingComponentError, match=r"pasta train vae data=DIR out=\S+ flat=true`"):
        load_flat(tmp_path / "nothing", [push])
    (tmp_path / "partial").mkdir()
    (tmp_path / "partial" / "vae").symlink_to(root / "vae")
    with pytest.raises(MissingComponentError, match=r"pasta train cost data=DIR out=\S+ flat=true"):
        load_flat(tmp_path / "partial", [push])


def test_entity_models_are_not_taken_for_flat_ones(flat_root, tmp_path):
    from pasta.io.checkpoint import save_checkpoint
    from pasta.nn.feasibility import SetFeasibility
    from pasta.plugins import get_plugins

    _, root, _ = flat_root
    mixed = tmp_path / "mixed"
    mixed.mkdir()
    for sub in ("vae", "cost"):
        (mixed / sub).symlink_to(root / sub)
    entity = SetFeasibility(1, 1, 5, 8)  # a 1 -> 1 entity network (push) must not pass for a flat one
    save_checkpoint(mixed / "feasibility" / "push", module="feasibility", tensors=entity.state_dict(),
                    config={**entity.config(), "skill": "push", "scope": "entity", "output_box": None, "train": {}})
    with pytest.raises(IncompatibleCheckpointError, match="scope"):
        load_flat(mixed, [get_plugins().skills.create("push")])
