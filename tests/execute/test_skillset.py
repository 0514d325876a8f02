"""Choosing the skill set (``skills=`` or every skill with trained weights): one rule for run, eval and plan."""

from __future__ import annotations

import pytest

from pasta.core.errors import ConfigError, MissingComponentError, PluginNotFoundError
from pasta.execute.skillset import choose_skills, parse_skill_names
from pasta.plugins import get_plugins
from pasta.plugins.registry import discover
from pasta.testing import AnalyticPlugin
from pasta.weights import ROOT


def models(tmp_path, *modules):
    """A models root holding (empty) checkpoint files for ``modules`` such as ``feasibility/cut``."""
    for rel in modules:
        (tmp_path / rel).mkdir(parents=True)
        for name in ("model.safetensors", "model.json"):
            (tmp_path / rel / name).write_text("")
    return tmp_path


BUILTIN = ("cut", "push", "roll")  # the built-in skills that ship trained weights


def others(*names):
    """The registered skills other than ``names``, in registry order (other installed plugins included)."""
    return [name for name in get_plugins().skills.names() if name not in names]


def test_shipped_weights_cover_the_builtin_skills():
    choice = choose_skills(None, ROOT)
    assert set(BUILTIN) <= set(choice.names) and not set(BUILTIN) & set(choice.left_out)
    # every registered skill is either chosen or left out (skills shipped without weights), in registry order
    assert choice.names == others(*choice.left_out) and set(choice.left_out) == set(others(*choice.names))
    assert (choice.warning() is None) == (not choice.left_out)


def test_skills_without_weights_are_left_out_with_one_warning_line(tmp_path):
    root = models(tmp_path, "vae", "feasibility/cut", "feasibility/push")  # its own VAE: nothing shipped is borrowed
    choice = choose_skills(None, root)
    left = others("cut", "push")  # roll, and any other registered skill
    assert choice.names == ["cut", "push"] and list(choice.left_out) == left and "roll" in left
    line = choice.warning()
    assert "\n" not in line
    assert line.startswith(f"warning: skills without trained weights under {root} are left out: {', '.join(left)}")
    assert f"`pasta train feasibility data=DIR out={root} skill=roll`" in line
    assert f"`pasta pipeline skills={','.join(left)} out={root}`" in line


def test_naming_a_skill_without_weights_is_an_error(tmp_path):
    root = models(tmp_path, "vae", "feasibility/cut", "feasibility/push")
    with pytest.raises(MissingComponentError, match=r"skill 'roll' has no feasibility network .*skill=roll"):
        choose_skills("cut,roll", root)
    assert choose_skills("push,cut", root).names == ["push", "cut"]  # the given order


def test_unknown_or_repeated_names_list_the_known_skills():
    known = get_plugins().skills.names()
    assert set(BUILTIN) <= set(known)
    with pytest.raises(PluginNotFoundError,
                       match=f"unknown skill 'rol'; did you mean 'roll'.*known skills: {', '.join(known)}$"):
        choose_skills("cut,rol", ROOT)
    with pytest.raises(ConfigError, match="names cut more than once"):
        parse_skill_names("cut,push,cut")
    assert parse_skill_names(" cut , ,push") == ["cut", "push"] and parse_skill_names("") == []


def test_learned_controllers_need_policies(tmp_path):
    root = models(tmp_path, "vae", "feasibility/cut", "feasibility/push", "feasibility/roll", "policy/cut")
    choice = choose_skills(None, root, policy=True)
    assert choice.names == ["cut"] and set(choice.left_out) == set(others("cut"))
    assert {"push", "roll"} <= set(choice.left_out)
    assert "policy (" in choice.warning() and "pasta train policy" in choice.warning()


def test_flat_method_looks_under_flat(tmp_path):
    root = models(tmp_path, "feasibility/cut", "flat/feasibility/push")
    assert choose_skills(None, root, flat=True).names == ["push"]


def test_skills_computing_their_own_feasibility_need_no_network(tmp_path):
    plugins = discover(extra={"analytic": AnalyticPlugin()})
    choice = choose_skills(None, models(tmp_path, "vae"), plugins=plugins)
    left = {name for name in plugins.skills.names() if name not in ("flatten", "move", "split")}
    assert choice.names == ["flatten", "move", "split"] and set(choice.left_out) == left and set(BUILTIN) <= left


def test_no_skill_with_weights_is_an_error(tmp_path):
    with pytest.raises(MissingComponentError, match=f"no registered skill has trained weights under {tmp_path}"):
        choose_skills(None, models(tmp_path, "vae"))


def test_require_says_why_a_needed_skill_is_missing(tmp_path):
    choice = choose_skills(None, models(tmp_path, "vae", "feasibility/cut", "feasibility/push"))
    with pytest.raises(ConfigError, match=r"task 'crs' needs the skills cut, push, roll; left out: 'roll': feasibility network"):
        choice.require(("cut", "push", "roll"), "task 'crs'")
    given = choose_skills("cut", tmp_path)
    with pytest.raises(ConfigError, match="'push': not in skills="):
        given.require(("cut", "push"), "skeleton=")


def test_no_message_suggests_training_into_the_installed_package(tmp_path):
    """A skill left out of the shipped root (a plugin installed without weights, as the test's analytic
    skills) is to be trained into a root of the user's, used with models=, never into pasta/weights."""
    plugins = discover(extra={"analytic": AnalyticPlugin()})
    choice = choose_skills(None, ROOT, plugins=plugins, policy=True)  # no policy ships for them
    assert "split" in choice.left_out
    line = choice.warning()
    assert f"out={ROOT}" not in line and "out=models" in line and "(then run with models=models)" in line


def test_a_root_that_trains_only_a_new_skill_uses_the_shipped_vae_cost_and_skills(tmp_path):
    from pasta.weights import module_dir, weight_overrides

    root = models(tmp_path, "feasibility/press", "feasibility/cut")
    assert module_dir(root, "vae") == ROOT / "vae" and module_dir(root, "cost") == ROOT / "cost"
    assert weight_overrides(root, []) == [f"encoder.weights={ROOT / 'vae'}", f"cost_model.weights={ROOT / 'cost'}"]
    # its own networks win; the skills it did not train come from the shipped weights
    assert module_dir(root, "feasibility/cut") == root / "feasibility" / "cut"
    assert module_dir(root, "feasibility/roll") == ROOT / "feasibility" / "roll"
    assert module_dir(root, "policy/roll") == ROOT / "policy" / "roll"
    assert module_dir(root, "feasibility/press") == root / "feasibility" / "press"
    assert module_dir(root, "feasibility/nothing") == root / "feasibility" / "nothing"  # named where the user looks
    choice = choose_skills(None, root)
    assert set(BUILTIN) <= set(choice.names) and "cut" in choice.names
    # networks that read latents belong to their VAE: a root with its own VAE borrows no cost and no skill
    own = models(tmp_path / "own", "vae", "feasibility/press")
    assert module_dir(own, "vae") == own / "vae" and module_dir(own, "cost") == own / "cost"
    assert module_dir(own, "feasibility/roll") == own / "feasibility" / "roll"


def test_a_models_root_that_does_not_exist_is_an_error_not_the_shipped_weights(tmp_path):
    from pasta.weights import models_root

    with pytest.raises(ConfigError, match=r"models=.*typo: the directory does not exist"):
        models_root(tmp_path / "typo")
    (tmp_path / "file").write_text("")
    with pytest.raises(ConfigError, match="is not a directory"):
        models_root(tmp_path / "file")
    assert models_root("") == ROOT and models_root(tmp_path) == tmp_path
