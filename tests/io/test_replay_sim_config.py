"""pasta replay --verify with a bad ``sim_config.json``: one line naming the key and the known keys, exit 2."""

from __future__ import annotations

import argparse
import json

import pytest

from pasta.io import RunLogger, replay
from pasta.io.run_log import INITIAL_STATE, SIM_CONFIG


def _run_file(path, sim_config: bytes):
    with RunLogger(path) as log:
        log.attach(SIM_CONFIG, sim_config, "application/json")
        log.attach(INITIAL_STATE, b"never read: the config is checked first")
        log.action(0, 0, "knife", [0.0, 0.0, 0.0])
    return path


def _verify(path) -> int:
    parser = argparse.ArgumentParser()
    replay.add_arguments(parser)
    return replay.run(parser.parse_args([str(path), "--verify"]))


@pytest.mark.parametrize("config, message", [
    (json.dumps({"n_grid": 64, "banana": 1}).encode(), r"unknown key 'banana'; known keys: E, arch, cpu_threads"),
    (json.dumps({"n_gird": 64}).encode(), r"unknown key 'n_gird'; did you mean 'n_grid'\?; known keys: "),
    (json.dumps({"n_grid": "sixty", "fast_math": False}).encode(), r"sim.n_grid='sixty': must be an int"),
    (json.dumps({"n_grid": 64, "knife_friction": 0.0}).encode(), r"older format \(knife_friction, no fast_math"),
    (b"[1, 2]", r"must hold a JSON object of simulator settings, got list"),
    (b"{not json", r"is not valid JSON"),
])
def test_bad_logged_sim_config_is_one_line_exit_2(tmp_path, capsys, config, message):
    import re

    path = _run_file(tmp_path / "r.mcap", config)
    assert _verify(path) == replay.EXIT_BAD_FILE
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert len(err) == 1 and err[0].startswith(f"pasta replay: error: {SIM_CONFIG} in {path}"), err
    assert re.search(message, err[0]), err
