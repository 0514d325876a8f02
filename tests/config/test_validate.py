"""Range checks of config values and command keys (issue 21): one line naming the key, exit code 2,
nothing computed first."""

from __future__ import annotations

import pytest

from pasta.cli import main
from pasta.config import load_config, section
from pasta.config.validate import (
    SEED_MAX,
    check_device,
    check_int,
    check_number,
    check_output_dir,
    check_output_file,
    check_seed,
    check_threads,
)
from pasta.core import ConfigError


@pytest.mark.parametrize("override, message", [
    ("planner.lr=nan", r"planner.lr=nan: must be a finite number > 0"),
    ("planner.lr=0", r"planner.lr=0.0: must be a finite number > 0"),
    ("planner.lr=-1", r"planner.lr=-1.0: must be a finite number > 0"),
    ("planner.lr=inf", r"planner.lr=inf: must be a finite number > 0"),
    ("planner.num_samples=0", r"planner.num_samples=0: must be an integer >= 1"),
    ("planner.refine_sequences=-1", r"planner.refine_sequences=-1: must be an integer >= 0"),
    ("planner.cost_weight=nan", r"planner.cost_weight=nan: must be a finite number >= 0"),
    ("planner.attention=all", r"planner.attention=all: must be one of sample, enumerate"),
    ("planner.draws=mine", r"planner.draws=mine: must be one of shared, sequence"),
    ("planner.halving_points=[0.5,1.5]", r"planner.halving_points\[1\]=1.5: must be a finite number in \(0, 1\)"),
    ("seed=-1", rf"seed=-1: must be an integer in \[0, {SEED_MAX}\]"),
    ("seed=99999999999999999999999", rf"seed=99999999999999999999999: must be an integer in \[0, {SEED_MAX}\]"),
    ("encoder.device=banana", r"encoder.device=banana: must be one of cpu, cuda, cuda:N"),
    ("cost_model.device=cuda:x", r"cost_model.device=cuda:x: must be one of cpu, cuda, cuda:N"),
    ("device=gpu", r"device=gpu: must be one of cpu, cuda, cuda:N"),
])
def test_out_of_range_values_name_key_value_and_range(override, message):
    with pytest.raises(ConfigError, match=message):
        load_config([override])


def test_sampling_planner_inherits_the_checks():
    with pytest.raises(ConfigError, match="planner.lr=nan"):
        load_config(["planner=sampling", "planner.lr=nan"])


def test_boundary_values_are_accepted():
    cfg = load_config(["planner.cost_weight=0", f"seed={SEED_MAX}", "planner.lr=1e-6", "planner.halving_points=[]"])
    assert section(cfg, "planner").cost_weight == 0.0 and cfg.seed == SEED_MAX and section(cfg, "planner").halving_points == []


def test_cuda_without_cuda_says_so(monkeypatch):
    import torch

    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)
    for override, key in (("device=cuda", "device"), ("encoder.device=cuda", "encoder.device"),
                          ("cost_model.device=cuda:0", "cost_model.device")):
        with pytest.raises(ConfigError, match=rf"^{key}=cuda(:0)?: CUDA is not available on this machine .*allowed here: cpu$"):
            load_config([override])


def test_cuda_device_index_is_checked_where_cuda_exists(monkeypatch):
    import torch

    monkeypatch.setattr(torch.cuda, "is_available", lambda: True)
    monkeypatch.setattr(torch.cuda, "device_count", lambda: 2)
    assert check_device("cuda") == "cuda" and check_device("cuda:1") == "cuda:1"
    with pytest.raises(ConfigError, match=r"device=cuda:2: this machine has 2 CUDA device\(s\); allowed: cpu, cuda, cuda:0..cuda:1"):
        check_device("cuda:2")


def test_scalar_checks():
    assert check_seed("7") == 7 and check_threads("0") == 0 and check_threads(3) == 3
    assert check_int("5", "horizon", low=0) == 5 and check_number("0.5", "x", low=0, high=1) == 0.5
    for call, message in [
        (lambda: check_threads("abc"), r"threads=abc: must be an integer in \[0, 1024\]"),
        (lambda: check_threads(-2), r"threads=-2: must be an integer in \[0, 1024\]"),
        (lambda: check_threads(10**6), r"threads=1000000: must be an integer in \[0, 1024\]"),
        (lambda: check_seed(True), r"seed=True: must be an integer"),
        (lambda: check_seed(2**64), r"seed=18446744073709551616: must be an integer in"),
        (lambda: check_int("1.5", "horizon", low=0), r"horizon=1.5: must be an integer >= 0"),
        (lambda: check_number("nan", "x", low=0, high=1), r"x=nan: must be a finite number in \[0, 1\]"),
    ]:
        with pytest.raises(ConfigError, match=message):
            call()


def test_output_paths(tmp_path):
    a_file = tmp_path / "taken"
    a_file.write_text("x")
    assert check_output_file(tmp_path / "new" / "deeper" / "run.mcap", "log") == tmp_path / "new" / "deeper" / "run.mcap"
    assert check_output_dir(tmp_path / "fresh" / "out", "out") == tmp_path / "fresh" / "out"
    assert check_output_dir(tmp_path, "out") == tmp_path
    with pytest.raises(ConfigError, match=r"^log=.*: is a directory; give a file path$"):
        check_output_file(tmp_path, "log")
    with pytest.raises(ConfigError, match=r"^summary=.*: '.*taken' is a file, so the path cannot be created$"):
        check_output_file(a_file / "x.png", "summary")
    with pytest.raises(ConfigError, match=r"^out=.*taken: exists and is not a directory; give a directory path$"):
        check_output_dir(a_file, "out")
    with pytest.raises(ConfigError, match=r"^out=: needs a path$"):
        check_output_dir("", "out")


def _one_error_line(capsys, key: str) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    lines = [ln for ln in err if "error" in ln]
    assert len(lines) == 1 and key in lines[0] and "Traceback" not in "\n".join(err), err
    return lines[0]


@pytest.fixture
def no_session(monkeypatch):
    """Make any model loading or planning fail loudly: the checks must come first."""
    import pasta.execute.session as session

    def refuse(*args, **kwargs):
        raise AssertionError("build_session called before the arguments were validated")

    monkeypatch.setattr(session, "build_session", refuse)


@pytest.mark.parametrize("argv, key", [
    (["run", "task=push", "threads=abc"], "threads=abc"),
    (["run", "task=push", "threads=-1"], "threads=-1"),
    (["run", "task=push", "horizon=two"], "horizon=two"),
    (["eval", "task=push", "threads=-1"], "threads=-1"),
    (["eval", "task=push", "horizon=-2"], "horizon=-2"),
])
def test_command_keys_are_checked_before_any_work(argv, key, no_session, capsys):
    assert main(argv) == 2
    _one_error_line(capsys, key)


def test_output_paths_are_checked_before_any_work(tmp_path, no_session, capsys):
    a_file = tmp_path / "plain"
    a_file.write_text("x")
    assert main(["run", "task=push", f"log={tmp_path}"]) == 2
    assert "is a directory" in _one_error_line(capsys, "log=")
    assert main(["run", "task=push", f"summary={a_file}/s.png"]) == 2
    assert "is a file" in _one_error_line(capsys, "summary=")
    assert main(["eval", "task=push", f"out={a_file}"]) == 2
    assert "not a directory" in _one_error_line(capsys, "out=")


@pytest.mark.parametrize("argv, key", [
    (["run", "task=push", "seed=-1"], "seed=-1"),
    (["run", "task=push", "seed=99999999999999999999999"], "seed=99999999999999999999999"),
    (["run", "task=push", "planner.lr=nan"], "planner.lr=nan"),
    (["run", "task=push", "encoder.device=banana"], "encoder.device=banana"),
    (["eval", "task=push", "planner.cost_weight=-2"], "planner.cost_weight=-2.0"),
    (["eval", "task=push", "device=banana"], "device=banana"),
    (["config", "planner.lr=nan"], "planner.lr=nan"),
])
def test_run_config_values_fail_with_one_line(argv, key, capsys):
    assert main(argv) == 2
    _one_error_line(capsys, key)


def test_cuda_for_learned_controllers_without_cuda(monkeypatch, capsys):
    import torch

    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)
    assert main(["run", "task=push", "device=cuda", "controller=learned"]) == 2
    assert "CUDA is not available" in _one_error_line(capsys, "device=cuda")
