import pytest

from pasta.cli import main
from pasta.config import load_config, section
from pasta.core import ConfigError, PluginNotFoundError


def test_defaults_pick_the_exhaustive_planner():
    cfg = load_config()
    assert cfg.seed == 0 and cfg.planner.name == "exhaustive"


def test_group_switch_swaps_the_whole_section():
    cfg = load_config(["planner=sampling", "planner.num_samples=123", "seed=7"])
    planner = section(cfg, "planner")
    assert type(planner).__name__ == "SamplingConfig" and planner.num_samples == 123 and cfg.seed == 7
    assert "halving_points" not in cfg.planner


def test_typo_suggests_the_closest_key():
    with pytest.raises(ConfigError, match=r"unknown config key 'planner.num_smaples'; did you mean 'planner.num_samples'\?"):
        load_config(["planner.num_smaples=1"])
    with pytest.raises(ConfigError, match=r"did you mean 'seed'"):
        load_config(["sed=1"])


def test_key_of_another_planner_is_rejected():
    with pytest.raises(ConfigError, match="unknown config key 'planner.halving_points'"):
        load_config(["planner=sampling", "planner.halving_points=[0.5]"])


def test_wrong_type_names_the_key():
    with pytest.raises(ConfigError, match="seed=abc: must be an integer"):
        load_config(["seed=abc"])


def test_unknown_group_choice_lists_known_planners():
    # a name no plugin registers (the example pasta-pinch registers "beam"); the built-ins are listed in
    # order, whatever third-party planners sit between them
    with pytest.raises(PluginNotFoundError, match="unknown planner 'not_a_planner'; known planners: ") as err:
        load_config(["planner=not_a_planner"])
    listed = str(err.value).split("known planners: ")[1].split(", ")
    builtins = [n for n in listed if n in ("exhaustive", "prefix_beam", "receding_horizon", "sampling")]
    assert builtins == ["exhaustive", "prefix_beam", "receding_horizon", "sampling"], listed


def test_malformed_override_and_name_override():
    with pytest.raises(ConfigError, match="must look like key=value"):
        load_config(["seed"])
    with pytest.raises(ConfigError, match="write planner=NAME"):
        load_config(["planner.name=sampling"])


def test_cli_prints_resolved_config(capsys):
    assert main(["config", "planner=sampling", "planner.num_samples=123"]) == 0
    out = capsys.readouterr().out
    assert "name: sampling" in out and "num_samples: 123" in out


def test_cli_reports_typo_with_exit_code_2(capsys):
    assert main(["config", "planner.num_smaples=1"]) == 2
    assert "did you mean 'planner.num_samples'" in capsys.readouterr().err


def test_every_setting_of_a_run_is_one_config_that_pasta_config_prints(capsys):
    from pasta.cli import main

    assert main(["config", "task=crs_distractors", "task.distractors=4", "sim.tool_friction.knife=0.2",
                 "skill.cut.max_steps=70", "execute.controller=learned", "perception.min_points=40"]) == 0
    out = capsys.readouterr().out
    for line in ("task:\n  name: crs_distractors", "  distractors: 4", "tool_friction:\n    knife: 0.2",
                 "skill:\n  cut:", "    max_steps: 70", "execute:\n  controller: learned", "  min_points: 40",
                 "planner:\n  name: exhaustive", "check:\n  box_margin:"):
        assert line in out, line


@pytest.mark.sim
def test_skill_and_simulator_settings_reach_the_session():
    from pasta.execute.session import build_session

    s = build_session("crs", ["skill.cut.max_steps=70", "sim.tool_friction.knife=0.2", "execute.regress_rise=0.3"])
    assert s.task.skill("cut").config.max_steps == 70 and s.task.sim_config.tool_friction == {"knife": 0.2}
    assert [sk.config.max_steps for sk in s.skills if sk.name == "cut"] == [70] and s.exe.regress_rise == 0.3
    assert s.task.sim_config.n_particles == s.task.config.n_particles  # the task's particle count
