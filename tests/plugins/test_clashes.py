"""Load-time rules: name clashes between plugins, skills whose tool is missing, failures printed once."""

from __future__ import annotations

import subprocess
import sys
import warnings

import pytest

from pasta.cli import main
from pasta.plugins import PluginLoadWarning, get_plugins
from pasta.plugins.registry import BUILTIN_DISTRIBUTION

# A third-party module whose parts the tests combine: a tool, a skill on it, a planner, a task.
HEADER = '''
import torch

from pasta.core import Planner, PluginConfig, Skill, SkillSpec, ToolSpec
from pasta.plugins import hookimpl
from dataclasses import dataclass


@dataclass
class BeamConfig(PluginConfig):
    width: int = 4


class BeamPlanner(Planner):
    name = "toy_beam"

    def plan(self, problem):
        raise NotImplementedError
'''

SKILL_ON = '''
class {cls}(Skill):
    spec = SkillSpec("{name}", n_in=2, n_out=1, tool="{tool}")

    def feasibility(self, u_in, u_out):
        return torch.ones(u_in.shape[0])


@hookimpl
def pasta_register_skills(register):
    register(spec={cls}.spec, factory="{module}:{cls}")
'''

TOOL = '''
@hookimpl
def pasta_register_tools(register):
    register(spec=ToolSpec("{tool}", description="from {module}"))
'''

PLANNER = '''
@hookimpl
def pasta_register_planners(register):
    register(name="toy_beam", factory="{module}:BeamPlanner", config=BeamConfig)
'''


def source(module: str, *parts: str, **fields: str) -> str:
    return HEADER + "".join(p.format(module=module, **fields) for p in parts)


def refusals(plugins, kind, name):
    return [f for f in plugins.failures if (f.kind, f.name) == (kind, name)]


def test_third_party_cannot_displace_a_builtin_skill(make_dist, fresh_plugins):
    """An entry point named like a built-in plugin, registering the built-in's skill name: the built-in is kept."""
    tool = get_plugins().skills.info("cut").spec.tool
    make_dist("aaa-evil", "evil_cut", source("evil_cut", SKILL_ON, TOOL, cls="Cut", name="cut", tool="claw"), entry="cut")
    with pytest.warns(PluginLoadWarning, match="skill 'cut' is already registered by the built-in"):
        plugins = fresh_plugins()
    info = plugins.skills.info("cut")
    assert (info.distribution, info.spec.tool, info.plugin) == (BUILTIN_DISTRIBUTION, tool, "cut")
    [failure] = refusals(plugins, "skill", "cut")
    assert failure.distribution == "aaa-evil" and BUILTIN_DISTRIBUTION in failure.error
    assert "claw" in plugins.tools  # the rest of that plugin loads: only the clashing name is refused


def test_entry_point_names_are_per_distribution(make_dist, fresh_plugins):
    """A third-party entry point named ``cut`` that registers other names clashes with nothing."""
    make_dist("pinch-pkg", "pinch_mod", source("pinch_mod", SKILL_ON, TOOL, cls="Pinch", name="squash", tool="claw"),
              entry="cut")
    with warnings.catch_warnings():
        warnings.simplefilter("error", PluginLoadWarning)
        plugins = fresh_plugins()
    assert not plugins.failures
    assert plugins.skills.info("squash").plugin == "cut" and plugins.skills.info("squash").distribution == "pinch-pkg"
    assert plugins.skills.info("cut").distribution == BUILTIN_DISTRIBUTION


def test_two_third_party_planners_with_one_name_load_neither(make_dist, fresh_plugins):
    make_dist("beam-one", "beam_one", source("beam_one", PLANNER), entry="beam")
    make_dist("beam-two", "beam_two", source("beam_two", PLANNER), entry="beam")
    with pytest.warns(PluginLoadWarning, match="planner 'toy_beam' is also registered by plugin 'beam' from beam-"):
        plugins = fresh_plugins()
    assert "toy_beam" not in plugins.planners
    failures = refusals(plugins, "planner", "toy_beam")
    assert sorted(f.distribution for f in failures) == ["beam-one", "beam-two"]
    one = next(f for f in failures if f.distribution == "beam-one")
    assert "beam-two 0.3" in one.error and "none of them is loaded" in one.error


def test_tool_clash_between_third_parties_refuses_the_tool_and_its_skills(make_dist, fresh_plugins):
    make_dist("grip-one", "grip_one", source("grip_one", TOOL, SKILL_ON, cls="Pinch", name="squash", tool="claw"))
    make_dist("grip-two", "grip_two", source("grip_two", TOOL, tool="claw"), entry="grip")
    with pytest.warns(PluginLoadWarning):
        plugins = fresh_plugins()
    assert "claw" not in plugins.tools and "squash" not in plugins.skills
    assert {f.distribution for f in refusals(plugins, "tool", "claw")} == {"grip-one", "grip-two"}
    [skill] = refusals(plugins, "skill", "squash")
    assert "drives tool 'claw', which no plugin registers; known tools:" in skill.error


def test_skill_with_unregistered_tool_fails_at_load_and_plugins_exits_1(make_dist, fresh_plugins, capsys):
    make_dist("pinch-pkg", "pinch_notool", source("pinch_notool", SKILL_ON, cls="Pinch", name="squash", tool="claw"))
    with pytest.warns(PluginLoadWarning, match="skill 'squash' drives tool 'claw', which no plugin registers"):
        plugins = fresh_plugins()
    assert "squash" not in plugins.skills
    [failure] = plugins.failures
    known = ", ".join(sorted(plugins.tools.names())) or "(none registered)"
    assert f"known tools: {known}" in failure.error
    assert main(["plugins"]) == 1
    out = capsys.readouterr().out
    assert "FAILED  skill 'squash' of plugin 'pinch' from pinch-pkg: skill 'squash' drives tool 'claw'" in out
    assert main(["plugins", "--json"]) == 1


def test_registering_a_tool_needs_a_tool_spec(make_dist, fresh_plugins):
    bad = HEADER + '''
@hookimpl
def pasta_register_tools(register):
    register(spec="claw")
'''
    make_dist("bad-tool", "bad_tool", bad)
    with pytest.warns(PluginLoadWarning, match=r"register a tool with spec=ToolSpec\(...\) only"):
        plugins = fresh_plugins()
    assert plugins.failures[0].distribution == "bad-tool"


def test_tools_are_data(fresh_plugins):
    from pasta.core import PluginValidationError, ToolSpec
    from pasta.plugins.registry import discover
    from pasta.testing import AnalyticPlugin

    plugins = discover(extra={"analytic": AnalyticPlugin()})
    spec = plugins.tools.spec("blade")
    assert isinstance(spec, ToolSpec) and plugins.tools.info("blade").factory == ""
    with pytest.raises(PluginValidationError, match="tool 'blade' is data"):
        plugins.tools.load("blade")


def test_each_failure_is_reported_once_per_command(make_dist, fresh_plugins):
    make_dist("broken-pkg", "broken_once", "import does_not_exist_anywhere\n", entry="broken")
    with pytest.warns(PluginLoadWarning) as record:
        fresh_plugins()
        get_plugins()
        get_plugins()
    assert len([w for w in record if issubclass(w.category, PluginLoadWarning)]) == 1


def test_cli_prints_a_failure_once_as_one_line(make_dist):
    path = make_dist("broken-pkg", "broken_cli", "import does_not_exist_anywhere\n", entry="broken")
    env = {"PYTHONPATH": str(path), "PATH": "/usr/bin:/bin"}
    out = subprocess.run([sys.executable, "-m", "pasta", "config"], capture_output=True, text=True, env=env, check=True)
    lines = [ln for ln in out.stderr.splitlines() if "broken" in ln]
    assert lines == ["warning: pasta plugin 'broken' from distribution 'broken-pkg': ModuleNotFoundError: "
                     "No module named 'does_not_exist_anywhere'"], out.stderr
    # a child process (a spawned worker) inherits the report and stays quiet
    code = "from pasta.plugins import get_plugins; get_plugins()"
    child = subprocess.run([sys.executable, "-W", "always", "-c", code], capture_output=True, text=True, check=True,
                           env={**env, "PASTA_PLUGIN_FAILURES_REPORTED": _digest_of_parent_report(path)})
    assert "broken" not in child.stderr, child.stderr


def _digest_of_parent_report(path) -> str:
    """What a parent process leaves in the environment after reporting the failures it saw."""
    code = ("import os, warnings; warnings.simplefilter('ignore'); from pasta.plugins import get_plugins; get_plugins(); "
            "print(os.environ['PASTA_PLUGIN_FAILURES_REPORTED'])")
    env = {"PYTHONPATH": str(path), "PATH": "/usr/bin:/bin"}
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True).stdout.strip()
