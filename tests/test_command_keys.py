"""Every key of every command is checked before any work (issue 41): for any set of ``key=value`` items,
drawn from the command's real keys (found from the dataclasses and the run config it reads, so a new key
is covered without new test code) plus unknown ones, with hostile values, ``pasta CMD`` exits 0, or 2 with
exactly one ``pasta CMD: error: ...`` line; never a traceback, never another exit code, never a hang,
and nothing is written before the checks pass.

Each command runs in-process (:func:`pasta.cli.main`) with the place where its work begins, :data:`WORK_STARTS`,
replaced by a stub that raises :class:`ChecksPassed`: reaching it counts as exit 0, and every check of the
command must happen before it. ``pasta config`` and ``pasta plugins`` do no heavy work and run for real.
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import io
import os
from dataclasses import MISSING, fields
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pasta.cli import build_parser, main


class ChecksPassed(Exception):
    """Raised where a command's work begins: every check of its keys passed (counts as exit code 0)."""


#: where each command's work begins (``module:attribute``, replaced by a stub raising :class:`ChecksPassed`):
#: all checks of the command's keys happen before this point
WORK_STARTS: dict[str, tuple[str, ...]] = {
    "plan": ("pasta.commands.plan:read_cloud",),  # the input clouds are read
    "run": ("pasta.execute.session:build_session",),  # models load, then the simulator starts
    "eval": ("pasta.execute.session:build_session",),
    "demos": ("pasta.demos.generate:generate_demos",),  # simulators start
    "train": ("pasta.train.run:train", "pasta.train.policy:train_command", "pasta.train.reset:train_command",
              "pasta.train.select:train_command", "pasta.train.evaluate:evaluate_command"),  # data loads, training
    "pipeline": ("pasta.pipeline.run:run_units",),  # the first unit runs
    "replay": ("pasta.io.replay:RunReader",),  # the run file is opened
    "config": (),
    "plugins": (),
}

#: a time bound per example: the checks of a command take well under a second
DEADLINE_MS = 5000
#: examples per command; derandomized, so CI sees the same ones (a deeper search: PASTA_KEY_EXAMPLES=2000, and
#: PASTA_KEY_SEED=1 for fresh random examples on every run)
EXAMPLES = int(os.environ.get("PASTA_KEY_EXAMPLES", "60"))

# ------------------------------------------------------------------------------------------------- values

HOSTILE_TEXT = ["", " ", "0", "1", "-1", "2", "-0", "00", "1e3", "1.5", "-2.5", "nan", "NaN", "-nan", "inf", "-inf",
                "1e308", "1e400", "-1e400", "1e-320", str(2**31), str(2**63), str(2**64), str(-2**63 - 1), str(10**30),
                "true", "false", "True", "yes", "null", "None", "~", "[]", "{}", "[1, 2]", "{a: 1}", "a=b=c", "=",
                "a,b,,c", ",", "cut,cut", "cut,nosuch", "task", "auto", "${oc.env:HOME}", "${seed}", "${nope}",
                "\\${x}", "'quoted'", '"', "no/such/dir", "no/such/file.npy", "/", "/proc/nope/x", "~/nope",
                ".", "..", "../x", "é中文", "💥", "a b", "\t", "x" * 300, "-", "--x", "cpu", "cuda", "cuda:7"]


def values(default: Any = None) -> st.SearchStrategy[str]:
    """A value for a key: hostile text, numbers of every kind, or the key's own default (so that other keys
    are reached)."""
    parts = [st.sampled_from(HOSTILE_TEXT),
             st.integers(min_value=-(2**70), max_value=2**70).map(str),
             st.floats(allow_nan=True, allow_infinity=True).map(repr),
             st.text(st.characters(blacklist_categories=("Cs",), blacklist_characters="\x00"), max_size=8)]
    if default is not None:
        parts.append(st.just(_text(default)))
    return st.one_of(*parts)


def _text(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (list, tuple)):
        return "[" + ",".join(map(str, value)) + "]"
    return "" if value is None else str(value)


UNKNOWN_KEYS = st.one_of(st.sampled_from(["nosuch", "seed2", "Seed", "horizn", "a.b", "a.b.c", ".", "x.", "planner.",
                                          "skill.cut.nosuch", "é", "ray.nosuch", "sim..n_grid"]),
                         st.from_regex(r"[a-z_][a-z_.]{0,12}", fullmatch=True))
MALFORMED = st.sampled_from(["novalue", "=x", " =x", "==", "a=b=c", ".=1"])


@st.composite
def items(draw, keys: dict[str, Any], base: list[str], max_items: int = 4) -> list[str]:
    """``base`` (the command's required keys, each sometimes dropped), then up to ``max_items`` items over
    ``keys`` (``{key: default}``), unknown keys and malformed items; a later item of the same key wins."""
    out = [item for item in base if draw(st.integers(0, 9)) > 0]
    names = sorted(keys)
    for _ in range(draw(st.integers(0, max_items))):
        kind = draw(st.integers(0, 19))
        if kind == 0:
            out.append(draw(MALFORMED))
        elif kind == 1:
            out.append(f"{draw(UNKNOWN_KEYS)}={draw(values())}")
        else:
            key = draw(st.sampled_from(names))
            out.append(f"{key}={draw(values(keys[key]))}")
    return out


# --------------------------------------------------------------------------------------------------- keys


def dataclass_keys(*classes: type, prefix: str = "") -> dict[str, Any]:
    """``{prefix + field: default}`` of every field of ``classes``."""
    out = {}
    for cls in classes:
        for f in fields(cls):
            default = f.default if f.default is not MISSING else (
                f.default_factory() if f.default_factory is not MISSING else None)  # type: ignore[misc]
            out[prefix + f.name] = default
    return out


@functools.cache
def run_config_keys() -> dict[str, Any]:
    """Every key of the run config, with every registered planner's, task's, encoder's and cost model's
    section, and the group switches with a registered name as their default."""
    from omegaconf import OmegaConf

    from pasta.config import GROUPS, load_config
    from pasta.plugins import get_plugins

    plugins = get_plugins()

    def flat(node: Any, prefix: str = "") -> dict[str, Any]:
        out: dict[str, Any] = {}
        for key, value in node.items():
            if isinstance(value, dict) and value:
                out.update(flat(value, f"{prefix}{key}."))
            elif key != "name":
                out[f"{prefix}{key}"] = value
        return out

    keys: dict[str, Any] = {}
    configs = [[]] + [[f"{group}={name}"] for group, kind in GROUPS.items() for name in plugins[kind].names()]
    for overrides in configs:
        keys.update(flat(OmegaConf.to_container(load_config(overrides), resolve=True)))
    for group, kind in GROUPS.items():
        keys[group] = plugins[kind].names()[0]
    keys.update({f"sim.tool_friction.{tool}": 0.5 for tool in plugins.tools.names()})
    return keys


def backend_keys() -> dict[str, Any]:
    return {"backend": "local", "ray.address": "", "ray.num_cpus": 0, "ray.object_store_mb": 256}


@functools.cache
def train_keys(module: str) -> dict[str, Any]:
    """The keys of ``pasta train MODULE``: its config dataclasses (those the trainer builds) and its paths."""
    from pasta.commands.train import _REQUIRED, _SKILL_KEY, module_configs

    configs = module_configs(module, {"skill": "cut"} if module == "feasibility" else {})
    keys = dataclass_keys(*(type(c) for c in configs))
    paths = _REQUIRED.get(module, ("data", "out"))
    keys.update({k: v for k, v in {"data": "data", "out": "models"}.items() if k in paths})
    keys.update({"skill": "cut"} if module in _SKILL_KEY else {})
    return keys


@functools.cache
def pipeline_keys() -> dict[str, Any]:
    """The pipeline's own keys and ``<stage>.<key>`` / ``<stage>.<skill>.<key>`` of every stage's configs."""
    from pasta.pipeline import STAGES, PipelineConfig

    keys = {**dataclass_keys(PipelineConfig), **backend_keys()}
    for st_ in STAGES:
        built = st_.build({"skill": "cut"} if st_.name == "demos" else {}, "cut" if st_.per_skill else None)
        classes = [type(c) for c in built]
        keys.update(dataclass_keys(*classes, prefix=f"{st_.name}."))
        if st_.per_skill:
            keys.update(dataclass_keys(*classes, prefix=f"{st_.name}.cut."))
    return keys


# ----------------------------------------------------------------------------------------------- running


@pytest.fixture(scope="module")
def _warm():
    """Every command once (imports, plugin discovery, the keys), so that no example pays for them."""
    run_config_keys(), pipeline_keys()
    for module in TRAIN_MODULES:
        train_keys(module)
    for command in WORK_STARTS:
        invoke([command, *(["vae"] if command == "train" else []), "nosuch=1"])


@pytest.fixture
def sandbox(_warm, tmp_path, monkeypatch):
    """A fresh empty working directory (checks must leave it empty) and the work boundaries stubbed."""
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)

    def stub(*args, **kwargs):
        raise ChecksPassed

    for targets in WORK_STARTS.values():
        for target in targets:
            module, _, attr = target.partition(":")
            monkeypatch.setattr(f"{module}.{attr}", stub)
    return tmp_path


def invoke(argv: list[str]) -> tuple[int, str]:
    """``pasta ARGV`` in-process: ``(exit code, stderr)``; reaching the work boundary is exit code 0."""
    import torch

    threads = torch.get_num_threads()
    out, err = io.StringIO(), io.StringIO()
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            code = main(argv)
    except ChecksPassed:
        code = 0
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 2)
    finally:
        torch.set_num_threads(threads)
    return code, err.getvalue()


def assert_clean(argv: list[str], work: Path | None = None, ok: tuple[int, ...] = (0,)) -> int:
    """Exit 0 (or another code of ``ok``), or exit 2 with exactly one ``pasta CMD: error:`` line (other stderr
    lines are warnings or notes), never a traceback; with ``work``, that directory is left empty."""
    code, err = invoke(argv)
    prog = "pasta " + argv[0]
    lines = err.splitlines()
    assert "Traceback" not in err, (argv, err)
    assert code in (*ok, 2), (argv, code, err)
    errors = [line for line in lines if line.startswith(f"{prog}: error: ")]
    if code == 2:
        assert len(errors) == 1 and lines[-1] == errors[0], (argv, err)
        others = [line for line in lines if line not in errors]
        assert all(line.startswith(("warning: ", "note: ", f"{prog}: warning: ")) for line in others), (argv, err)
    else:
        assert not errors, (argv, err)
    if work is not None:
        assert not any(work.iterdir()), (argv, sorted(map(str, work.rglob("*"))))
    return code


SETTINGS = settings(max_examples=EXAMPLES, deadline=DEADLINE_MS, derandomize=not os.environ.get("PASTA_KEY_SEED"),
                    database=None,
                    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])


def _cloud_files(root: Path) -> tuple[Path, Path]:
    import numpy as np

    rng = np.random.default_rng(0)
    obs, goal = root / "obs.npy", root / "goal.npy"
    np.save(obs, (0.4 + 0.1 * rng.random((200, 3))).astype(np.float32))
    np.save(goal, (0.5 + 0.1 * rng.random((200, 3))).astype(np.float32))
    return obs, goal


# -------------------------------------------------------------------------------------------- properties


@SETTINGS
@given(data=st.data())
def test_config(sandbox, data):
    assert_clean(["config", *data.draw(items(run_config_keys(), []))], sandbox / "work")


@SETTINGS
@given(data=st.data())
def test_plan(sandbox, data):
    from pasta.commands.plan import COMMAND_KEYS

    obs, goal = _cloud_files(sandbox)
    keys = {**run_config_keys(), **{k: v for k, v in COMMAND_KEYS.items()}, "obs": obs, "goal": goal}
    assert_clean(["plan", *data.draw(items(keys, [f"obs={obs}", f"goal={goal}", "out=plan_out"]))], sandbox / "work")


@SETTINGS
@given(data=st.data())
def test_run(sandbox, data):
    from pasta.commands.run import RunArgs

    keys = {**run_config_keys(), **dataclass_keys(RunArgs), "controller": "heuristic"}
    assert_clean(["run", *data.draw(items(keys, ["task=crs"]))], sandbox / "work")


@SETTINGS
@given(data=st.data())
def test_eval(sandbox, data):
    from pasta.commands.eval import EvalArgs

    keys = {**run_config_keys(), **dataclass_keys(EvalArgs), **backend_keys(), "controller": "heuristic"}
    keys.pop("seed")  # pasta eval refuses seed= (it runs the fixed test seeds): drawn as a hostile key below
    assert_clean(["eval", *data.draw(items({**keys, "seed": 0}, ["task=crs", "num=2", "out=runs"]))], sandbox / "work")


@SETTINGS
@given(data=st.data())
def test_demos(sandbox, data):
    from pasta.demos.generate import DemoConfig

    keys = {**dataclass_keys(DemoConfig), **backend_keys()}
    assert_clean(["demos", *data.draw(items(keys, ["skill=cut", "num=2", "out=demos", "workers=0"]))], sandbox / "work")


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    """A tiny dataset (a manifest and two cut demonstrations) and a models root whose VAE and cut policy
    exist (empty files: nothing loads them before the work starts), so that every train key is reached."""
    from synthetic_demos import write_synthetic_dataset

    data = write_synthetic_dataset(tmp_path_factory.mktemp("data"), per_skill=2, skills=("cut",), steps=3,
                                   num_points=200)
    models = tmp_path_factory.mktemp("models")
    for module in ("vae", "policy/cut"):
        (models / module).mkdir(parents=True)
        for name in ("model.safetensors", "model.json"):
            (models / module / name).write_bytes(b"")
    return data, models


TRAIN_MODULES = ("vae", "feasibility", "cost", "policy", "reset", "select", "evaluate")


@pytest.mark.parametrize("module", TRAIN_MODULES)
def test_train(module, sandbox, dataset):
    base = {"vae": ["data", "out"], "feasibility": ["data", "out", "skill"], "cost": ["data", "out"],
            "policy": ["data", "out", "skill"], "reset": ["data", "out", "skill"], "select": ["out", "skill"],
            "evaluate": []}[module]
    data, models = dataset
    given_ = {"data": f"data={data}", "out": f"out={models}", "skill": "skill=cut"}

    @SETTINGS
    @given(data=st.data())
    def check(data):
        assert_clean(["train", module, *data.draw(items(train_keys(module), [given_[k] for k in base]))],
                     sandbox / "work")

    check()


@SETTINGS
@given(data=st.data())
def test_pipeline(sandbox, data):
    assert_clean(["pipeline", *data.draw(items(pipeline_keys(), ["out=models", "data=demos"]))], sandbox / "work")


# ------------------------------------------------------------------------------ commands with mode flags


def _subparser(command: str) -> argparse.ArgumentParser:
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return sub.choices[command]


def _flags(command: str) -> list[str]:
    """The mode flags of a command, found from its parser (every option but --help)."""
    return [a.option_strings[0] for a in _subparser(command)._actions if a.option_strings and a.dest != "help"]


@st.composite
def with_flags(draw, command: str, argv: list[str]) -> list[str]:
    """``argv`` with the command's mode flags put in at drawn places: modes go anywhere on the line."""
    out = list(argv)
    for _ in range(draw(st.integers(0, 3))):
        out.insert(draw(st.integers(0, len(out))), draw(st.sampled_from(_flags(command))))
    return out


@SETTINGS
@given(data=st.data())
def test_replay(sandbox, data):
    from pasta.io.replay import ReplayArgs

    run_file = data.draw(st.one_of(st.just(str(sandbox / "run.mcap")), values()))
    argv = [run_file, *data.draw(items(dataclass_keys(ReplayArgs), []))]
    assert_clean(["replay", *data.draw(with_flags("replay", argv))], sandbox / "work")


@SETTINGS
@given(data=st.data())
def test_plugins(sandbox, data):
    from pasta.commands.plugins import PluginsArgs
    from pasta.plugins import get_plugins

    # `pasta plugins` exits 1 when an installed plugin failed to load (the environment's, not a usage error)
    broken = bool(get_plugins(report=False).failures)
    argv = data.draw(with_flags("plugins", data.draw(items(dataclass_keys(PluginsArgs), []))))
    assert_clean(["plugins", *argv], sandbox / "work", ok=(0, 1) if broken else (0,))


def test_settings_are_key_value_and_modes_are_flags():
    """The one style of `pasta --help`: no option of any command takes a value (a setting is key=value)."""
    commands = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction)).choices
    for name in commands:
        valued = [a.option_strings[0] for a in _subparser(name)._actions if a.option_strings and a.nargs != 0]
        assert not valued, (name, valued)


# ---------------------------------------------------------------------------------------------- threads=N

#: the commands that only print; every other command computes and takes threads=N
PRINTING = ("config", "plugins")


def _computing_argv(command: str, root: Path, dataset: tuple[Path, Path]) -> list[str]:
    """Items with which ``command`` (``train MODULE``: one module) reaches its work."""
    data, models = dataset
    if command.startswith("train "):
        module = command.split()[1]
        need = {"data": f"data={data}", "out": f"out={models}", "skill": "skill=cut"}
        base = {"vae": ["data", "out"], "feasibility": ["data", "out", "skill"], "cost": ["data", "out"],
                "policy": ["data", "out", "skill"], "reset": ["data", "out", "skill"], "select": ["out", "skill"],
                "evaluate": []}[module]
        return ["train", module, *(need[k] for k in base)]
    obs, goal = _cloud_files(root)
    return {"plan": ["plan", f"obs={obs}", f"goal={goal}", "out=plan_out"],
            "run": ["run", "task=crs"],
            "eval": ["eval", "task=crs", "num=2", "out=runs"],
            "demos": ["demos", "skill=cut", "num=2", "out=demos", "workers=0"],
            "pipeline": ["pipeline", "out=models", "data=demos", "stages=demos", "skills=cut"],
            "replay": ["replay", str(root / "run.mcap"), "--verify"]}[command]


COMPUTING = ["plan", "run", "eval", "demos", "pipeline", "replay", *(f"train {m}" for m in TRAIN_MODULES)]


def test_every_command_is_computing_or_printing():
    commands = set(next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction)).choices)
    assert commands == {c.split()[0] for c in COMPUTING} | set(PRINTING)


def test_help_states_the_one_style(capsys):
    import re

    with pytest.raises(SystemExit) as exc:
        main(["--help"])
    text = capsys.readouterr().out
    assert exc.value.code == 0
    for needle in ("settings   key=value", "a later item of the same key wins", "`pasta config", "modes      --flags",
                   "exit codes: 0 ok, 1 the work failed, 2 usage", "3 a plan flagged unreachable"):
        assert needle in text, needle
    named = re.search(r"threads=N  on every command that computes \(([^)]*)\)", text)
    assert named and set(named.group(1).split(", ")) == {c.split()[0] for c in COMPUTING}, text


@pytest.mark.parametrize("command", COMPUTING)
def test_every_computing_command_takes_threads(command, sandbox, dataset):
    argv = _computing_argv(command, sandbox, dataset)
    for value in ("0", "2"):
        code, err = invoke([*argv, f"threads={value}"])
        assert code == 0 and "Traceback" not in err, (argv, value, err)  # checked, then the work starts
    assert "threads=-1: must be an integer in [0, " in _one_error([*argv, "threads=-1"])
    assert not any((sandbox / "work").iterdir())


def test_every_command_is_covered():
    """A new command needs its property test here and its entry in WORK_STARTS."""
    commands = set(next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction)).choices)
    tested = {name[len("test_"):] for name in globals() if name.startswith("test_")}
    assert commands <= tested, commands - tested
    assert commands == set(WORK_STARTS)


# ------------------------------------------------------------------------------------------- named cases


def _one_error(argv: list[str]) -> str:
    """Run ``pasta ARGV`` (work boundaries stubbed by the caller's ``sandbox``); assert exit 2 and one error
    line; return it."""
    code, err = invoke(argv)
    lines = err.splitlines()
    assert code == 2 and len(lines) == 1 and lines[0].startswith(f"pasta {argv[0]}: error: "), (argv, code, err)
    return lines[0]


@pytest.mark.parametrize("command", ["run", "eval", "plan"])
def test_horizon_is_bounded_alike_in_plan_run_and_eval(sandbox, command):
    from pasta.config import MAX_HORIZON

    obs, goal = _cloud_files(sandbox)
    base = [f"obs={obs}", f"goal={goal}"] if command == "plan" else ["task=crs"]
    for value in ("50", str(MAX_HORIZON + 1), "0", "", "-1", "2.5", "nan"):
        line = _one_error([command, *base, f"horizon={value}"])
        hint = "(omit horizon= for the task's horizon"
        assert f"horizon={value}: must be an integer in [1, {MAX_HORIZON}] {hint}" in line
    assert invoke([command, *base, f"horizon={MAX_HORIZON}"])[0] == 0  # the bound itself reaches the work
    assert not any((sandbox / "work").iterdir())


def test_run_horizon_50_never_reaches_the_planner(tmp_path, monkeypatch):
    """Without stubs: `pasta run horizon=50` once hung in the skeleton enumeration."""
    import pasta.execute.session as session

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(session, "build_session", lambda *a, **k: pytest.fail("a session was built"))
    assert _one_error(["run", "task=crs", "horizon=50"]).endswith("(omit horizon= for the task's horizon; "
                                                                  "pasta plan's is 3)")


def _planners_of_this_checkout() -> bool:
    import pasta_planner_exhaustive

    return Path(pasta_planner_exhaustive.__file__).resolve().is_relative_to(Path(__file__).resolve().parents[1])


@pytest.mark.skipif(not _planners_of_this_checkout(), reason="the planner plugins are imported from another checkout")
@pytest.mark.parametrize("override", ["planner.max_horizon=50", "planner=prefix_beam planner.max_horizon=11",
                                      "planner=receding_horizon planner.window=50"])
def test_planner_horizons_share_the_bound(sandbox, override):
    assert "must be an integer in [" in _one_error(["run", "task=crs", *override.split()])


def test_demos_seed_is_checked_before_a_simulator_starts(tmp_path, monkeypatch):
    import pasta.sim

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(pasta.sim, "Simulator", lambda *a, **k: pytest.fail("a simulator started"))
    for value, message in (("-1", "seed=-1: must be an integer in [0, 4294967295]"),
                           ("1.5", "seed=1.5 for `pasta demos`: must be an integer"),
                           (str(2**40), f"seed={2**40}: must be an integer in [0, 4294967295]")):
        assert message in _one_error(["demos", "skill=cut", f"seed={value}", "num=1", "workers=0", "out=demos"])
    assert not any(tmp_path.iterdir())


@pytest.mark.parametrize("argv, message", [
    (["config", "seed=${oc.env:HOME}"], "seed=${oc.env:HOME}: ${...} interpolations are not supported"),
    (["config", "models=a\nb", "seed=x"], r"seed=x: must be an integer"),
    (["config", 'check.max_z="'], "check.max_z=\": cannot be read as a value"),
    (["config", "seed=a\x1eb"], r"seed=a\x1eb: cannot be read as a value"),
    (["config", "planner="], "planner=: names no planner; registered planners: "),
    (["config", "execute=heuristic"], "'execute' is a section, not a setting; set its keys: execute.controller"),
    (["config", "task.distractors=4"], "'task.distractors' is a setting of the chosen task, and none is chosen"),
    (["config", "models=[a, b]"], "models=[a, b]: must be a single value, not a list or a mapping"),
    (["plugins", "kind=nosuch"], "kind=nosuch: must be one of skill, tool, planner, encoder, cost_model, task"),
    (["plugins", "--json", "knd=skill"], "unknown key 'knd' for `pasta plugins`; did you mean 'kind'?"),
    (["plugins", "--kind", "skill"], "unrecognized arguments: --kind"),
    (["run", "--x"], "unrecognized arguments: --x"),
    (["eval", "task=crs", "num=1001"], "num=1001: must be an integer in [1, 1000]"),
    (["eval", "task=crs", "workers=100000"], "workers=100000: must be an integer in [0, 1024]"),
    (["plan", "obs=no/such.npy", "goal=no/such.npy"], "obs=no/such.npy: the file does not exist"),
    (["replay", "run.mcap", "every=0"], "every=0: must be an integer >= 1"),
    (["replay", "run.mcap", "fps=nan"], "fps=nan: must be a finite number in (0, 1000]"),
    (["replay", "run.mcap", "--verify", "tolerence=1e-3"], "unknown key 'tolerence' for `pasta replay`; did you mean 'tolerance'?"),
    (["replay", "run.mcap", "up_axis=w", "--recover"], "up_axis=w: must be one of x, y, z"),
    (["replay", "run.mcap", "--every", "2"], "unrecognized arguments: --every"),
    (["demos", "skill=cut", "thread=1"], "unknown key 'thread' for `pasta demos`; did you mean 'threads'?"),
    (["train", "vae", "data=no/such", "out=models"], "data=no/such: the directory does not exist"),
    (["train", "vae", "data=.", "out=models", "lr=nan"], "lr=nan: must be a finite number in (0, 1]"),
    (["train", "vae", "data=.", "out=models", "emd_weight=inf"], "emd_weight=inf: must be a finite number >= 0"),
    (["train", "feasibility", "data=.", "out=models", "skill=cut", "shift_entities=some"],
     "shift_entities=some: must be one of all, one"),
    (["train", "evaluate", "skills=knead"], "unknown skill 'knead' for demonstrations"),
    (["pipeline", "num_demos=0"], "num_demos=0: must be an integer in [1, 1000000]"),
    (["pipeline", "vae.epochs=-1"], "vae: epochs=-1: must be an integer in [1, 100000]"),
])
def test_named_bad_values_are_one_line(sandbox, argv, message):
    assert message in _one_error(argv)
    assert not any((sandbox / "work").iterdir())


def test_a_given_skeleton_sets_the_horizon(sandbox):
    line = _one_error(["run", "task=crs", "skeleton=cut,push", "horizon=3"])
    assert "skeleton=cut,push has 2 steps but horizon=3: a given skeleton sets the horizon (omit horizon=)" in line


def test_the_task_skeleton_bounds_the_horizon_before_any_model_loads(monkeypatch):
    import pasta.execute.skillset as skillset
    from pasta.core import ConfigError
    from pasta.execute.session import build_session

    monkeypatch.setattr(skillset, "choose_skills", lambda *a, **k: pytest.fail("went on to the models"))
    with pytest.raises(ConfigError, match=r"^horizon=5: skeleton=task plans the task's 3-step chain \(cut,push,roll\)"):
        build_session("crs", skeleton="task", horizon=5)


def test_every_argparse_error_is_one_line(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["nosuch"])
    assert exc.value.code == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith("pasta: error: argument COMMAND: invalid choice: 'nosuch'"), err
