"""A throwaway third-party distribution (a *.dist-info with entry_points.txt on sys.path, no pip)."""

import subprocess
import sys

import pytest

from pasta.cli import main
from pasta.plugins import PluginLoadWarning
from pasta.testing import check_skill

PINCH_MODULE = '''
from dataclasses import dataclass

import torch

from pasta.core import Planner, PluginConfig, Skill, SkillSpec, ToolSpec
from pasta.plugins import hookimpl

SPEC = SkillSpec("squash", n_in=2, n_out=1, tool="claw", description="squeeze two pieces into one")


class PinchSkill(Skill):
    spec = SPEC

    def feasibility(self, u_in, u_out):
        self._check_tuple(u_in, u_out)
        return torch.sigmoid(-(u_in.sum(1) - u_out[:, 0]).pow(2).sum(-1))


@dataclass
class BeamConfig(PluginConfig):
    width: int = 4


class BeamPlanner(Planner):
    name = "toy_beam"

    def plan(self, problem):
        raise NotImplementedError


@hookimpl
def pasta_register_tools(register):
    register(spec=ToolSpec("claw", description="two-finger parallel claw"))


@hookimpl
def pasta_register_skills(register):
    register(spec=SPEC, factory="pinch_plugin:PinchSkill")


@hookimpl
def pasta_register_planners(register):
    register(name="toy_beam", factory="pinch_plugin:BeamPlanner", config=BeamConfig, summary="toy beam search")
'''


@pytest.fixture
def pinch_dist(make_dist):
    return make_dist("pinch-pkg", "pinch_plugin", PINCH_MODULE)


def test_third_party_skill_and_planner_appear_and_disappear(pinch_dist, monkeypatch, fresh_plugins, capsys):
    plugins = fresh_plugins()
    info = plugins.skills.info("squash")
    assert (info.spec.n_in, info.spec.n_out, info.distribution, info.version) == (2, 1, "pinch-pkg", "0.3")
    skill = plugins.skills.create("squash")
    check_skill(skill)
    planner = plugins.planners.create("toy_beam")
    assert planner.config.width == 4 and planner.config.name == "toy_beam"
    assert "cut" in plugins.skills  # built-ins still there

    assert main(["plugins"]) == 0
    out = capsys.readouterr().out
    assert "squash" in out and "2->1 (claw)" in out and "pinch-pkg" in out and "toy_beam" in out

    monkeypatch.undo()
    sys.modules.pop("pinch_plugin", None)
    plugins = fresh_plugins()
    assert "squash" not in plugins.skills and "toy_beam" not in plugins.planners


def test_third_party_plugin_listed_by_cli_subprocess(pinch_dist):
    env = {"PYTHONPATH": str(pinch_dist), "PATH": "/usr/bin:/bin"}
    out = subprocess.run([sys.executable, "-m", "pasta", "plugins", "kind=skill"], capture_output=True, text=True, env=env, check=True)
    assert "squash" in out.stdout and "pinch-pkg" in out.stdout


def test_broken_plugin_is_reported_and_others_load(make_dist, fresh_plugins):
    make_dist("broken-pkg", "broken_plugin", "import does_not_exist_anywhere\n", entry="broken")
    with pytest.warns(PluginLoadWarning, match=r"plugin 'broken' from distribution 'broken-pkg'.*does_not_exist_anywhere"):
        plugins = fresh_plugins()
    assert [(f.plugin, f.distribution) for f in plugins.failures] == [("broken", "broken-pkg")]
    assert {"cut", "push", "roll"} <= set(plugins.skills.names())
    assert "exhaustive" in plugins.planners


def test_misspelled_hook_is_rejected_at_load(make_dist, fresh_plugins):
    source = "from pasta.plugins import hookimpl\n\n@hookimpl\ndef pasta_register_skils(register):\n    pass\n"
    make_dist("typo-pkg", "typo_plugin", source, entry="typo")
    with pytest.warns(PluginLoadWarning, match="pasta_register_skils"):
        plugins = fresh_plugins()
    assert plugins.failures[0].plugin == "typo"
