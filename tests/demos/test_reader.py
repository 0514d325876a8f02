import json

import numpy as np
import pytest

from pasta.core.errors import InputError
from pasta.demos.data import load_demo, load_demos, read_manifest, split_by_demo
from synthetic_demos import synthetic_demo, write_synthetic_dataset


@pytest.fixture(scope="module")
def three_demos(tmp_path_factory):
    """A dataset of 3 synthetic cut demonstrations, 4 steps each, 400 points."""
    return write_synthetic_dataset(tmp_path_factory.mktemp("demos"), per_skill=3, skills=("cut",), steps=4, num_points=400)


def test_written_format_loads_without_pickle(three_demos):
    path = three_demos / "cut" / "demo_00000.npz"
    with np.load(path, allow_pickle=False) as f:
        assert f["dough"].shape == (5, 400, 3) and f["dough"].dtype == np.float32
        assert f["tool_points"].shape[:1] == (5,) and f["tool_pose"].shape == (5, 7) and f["action"].shape[0] == 4
        assert f["skill"].shape == () and str(f["skill"]) == "cut"
        assert json.loads(str(f["params"]))["generator"] == "synthetic"
    demo = load_demo(path)
    assert demo.key == "cut/00000" and demo.num_steps == 4
    assert read_manifest(three_demos)["skills"] == {"cut": 3}


@pytest.mark.parametrize("skill", ["cut", "push", "roll"])
def test_synthetic_skills_change_the_dough(skill):
    from pasta.core.decompose import decompose

    arrays = synthetic_demo(skill, seed=1, steps=6)
    first, last = decompose(arrays["dough"][0]), decompose(arrays["dough"][-1])
    assert len(first) == 1 and len(last) == (2 if skill == "cut" else 1)
    if skill == "roll":
        assert np.ptp(last[0][:, 1]) < 0.3 * np.ptp(first[0][:, 1])


def test_split_is_by_demonstration_and_seeded(tmp_path):
    root = write_synthetic_dataset(tmp_path, per_skill=5, skills=("push", "roll"), steps=1, num_points=50)
    demos = load_demos(root)
    train, val = split_by_demo(demos, val_fraction=0.2, seed=3)
    keys_t, keys_v = {d.key for d in train}, {d.key for d in val}
    assert not keys_t & keys_v and len(keys_t | keys_v) == 10
    assert sorted(d.skill for d in val) == ["push", "roll"]
    again = split_by_demo(demos, val_fraction=0.2, seed=3)[1]
    assert [d.key for d in again] == [d.key for d in val]


def test_missing_dataset_and_skill(tmp_path):
    with pytest.raises(InputError, match="does not exist"):
        load_demos(tmp_path / "nope")
    tmp_path.joinpath("x").mkdir()
    with pytest.raises(InputError, match="manifest.json"):
        load_demos(tmp_path / "x")
    root = write_synthetic_dataset(tmp_path / "d", per_skill=1, skills=("push",), steps=1, num_points=20)
    with pytest.raises(InputError, match="skill"):
        load_demos(root, ["cut"])


def test_demos_of_a_variant_kept_for_some_stages_are_left_out_of_the_others(tmp_path):
    from pasta.tasks.npz import write_npz

    root = write_synthetic_dataset(tmp_path, per_skill=3, skills=("cut",), steps=1, num_points=30)
    path = root / "cut" / "demo_00002.npz"  # as `pasta demos scene=V` writes it for a variant with stages=("reset",)
    with np.load(path, allow_pickle=False) as f:
        arrays = {k: f[k] for k in f.files}
    arrays["params"] = np.array(json.dumps({**json.loads(str(arrays["params"])), "variant": "long", "stages": ["reset"]}))
    write_npz(path, arrays)
    assert len(load_demos(root)) == 3 and len(load_demos(root, ["cut"], stage="reset")) == 3
    assert [d.index for d in load_demos(root, ["cut"], stage="policy")] == [0, 1]
    assert len(load_demos(root, stage="vae")) == 2
    for i in (0, 1):
        (root / "cut" / f"demo_{i:05d}.npz").unlink()
    with pytest.raises(InputError, match="training stage 'feasibility'"):
        load_demos(root, ["cut"], stage="feasibility")


def test_variant_record_names_the_variant_and_its_stages():
    from pasta.core import DemoVariant, Skill, SkillSpec
    from pasta.core.errors import ConfigError
    from pasta.demos.generate import variant_record

    class Knife(Skill):
        spec = SkillSpec("knife", 1, 2, "knife")
        demo_variants = {"wide": DemoVariant(), "long": DemoVariant(stages=("reset",)), "bad": DemoVariant(stages=("resets",))}

    assert variant_record(Knife, "default") == {}
    assert variant_record(Knife, "wide") == {"variant": "wide"}
    assert variant_record(Knife, "long") == {"variant": "long", "stages": ["reset"]}
    with pytest.raises(ConfigError, match="unknown training stages \\['resets'\\]"):
        variant_record(Knife, "bad")
