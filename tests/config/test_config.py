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
    assert "successive_halving" not in cfg.planner


def test_typo_suggests_the_closest_key():
    with pytest.raises(ConfigError, match=r"unknown config key 'planner.num_smaples'; did you mean 'planner.num_samples'\?"):
        load_config(["planner.num_smaples=1"])
    with pytest.raises(ConfigError, match=r"did you mean 'seed'"):
        load_config(["sed=1"])


def test_key_of_another_planner_is_rejected():
    with pytest.raises(ConfigError, match="unknown config key 'planner.successive_halving'"):
        load_config(["planner=sampling", "planner.successive_halving=true"])


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
