"""The README and the user docs name only settings that exist: every ``section.key=`` of the run config and
every ``key=value`` of a ``pasta plan|run|eval|config|demos|replay|plugins`` command line they show is a key
pasta accepts.

History (CHANGELOG.md, docs/experiments/) may name settings that were deleted since; it is not checked.
"""

from __future__ import annotations

import re
from dataclasses import fields, is_dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
SECTIONS = ("planner", "encoder", "cost_model", "perception", "check", "execute", "sim", "skill", "task")
DOTTED = re.compile(r"(?<![\w./-])((?:" + "|".join(SECTIONS) + r")\.[A-Za-z_][\w.]*)=")
#: a key of a section no code object is named after, in backticks, with or without a value: `execute.regress_near`
QUOTED = re.compile(r"`((?:execute|perception|check)\.[A-Za-z_][\w.]*)(?:=[^`]*)?`")
#: misspelt on purpose: the README shows the error a typo gets
DELIBERATE = {"planner.num_smaples"}
COMMAND = re.compile(r"(?:^|[\s`(])(?:\.venv/bin/)?(?:pasta|python -m pasta) (plan|run|eval|config|demos|replay|plugins)\b"
                     r"([^`\n]*)")


def _fields(obj) -> set[str]:
    return {f.name for f in fields(obj)} if is_dataclass(obj) else set(obj or ())


def valid_keys() -> dict[str, set[str]]:
    """Per command, the keys it accepts (run-config keys, dotted, plus the command's own)."""
    from pasta.commands.eval import EvalArgs
    from pasta.commands.plan import COMMAND_KEYS
    from pasta.commands.run import RunArgs
    from pasta.config import load_config
    from pasta.config.run import RunConfig
    from pasta.plugins import get_plugins

    plugins = get_plugins()

    def flat(node, prefix=""):
        from omegaconf import DictConfig

        out = set()
        for key, value in node.items():
            out.add(f"{prefix}{key}")
            if isinstance(value, DictConfig):
                out |= flat(value, f"{prefix}{key}.")
        return out

    keys = flat(load_config([]))
    for name in plugins.planners.names():
        keys |= flat(load_config([f"planner={name}"]))
    for name in plugins.tasks.names():
        keys |= flat(load_config([f"task={name}"]))
    keys |= {f"sim.tool_friction.{t}" for t in plugins.tools.names()} | {"controller"} | set(_fields(RunConfig))
    from pasta.distributed import BACKEND_KEYS

    from pasta.commands.plugins import PluginsArgs
    from pasta.demos import DemoConfig
    from pasta.io.replay import ReplayArgs

    backend = set(BACKEND_KEYS)
    return {"config": keys, "run": keys | _fields(RunArgs), "eval": keys | _fields(EvalArgs) | backend,
            "plan": keys | set(COMMAND_KEYS), "demos": _fields(DemoConfig) | backend, "replay": _fields(ReplayArgs),
            "plugins": _fields(PluginsArgs)}


def _mentions():
    for path in DOCS:
        text = path.read_text()
        for m in (*DOTTED.finditer(text), *QUOTED.finditer(text)):
            key = m.group(1).rstrip(".")
            if key not in DELIBERATE and not key.split(".")[-1].isupper():  # `planner.KEY=`: a placeholder
                yield path, "config", key
        for m in COMMAND.finditer(text):
            for token in m.group(2).split():
                key, eq, _ = token.partition("=")
                if eq and re.fullmatch(r"[A-Za-z_][\w.]*", key) and key not in DELIBERATE \
                        and not key.split(".")[-1].isupper():
                    yield path, m.group(1), key


def test_docs_name_only_keys_that_exist():
    keys = valid_keys()
    unknown = sorted({f"{path.relative_to(ROOT)}: {key}= ({command})" for path, command, key in _mentions()
                      if key not in keys[command]})
    assert not unknown, "the docs name settings that do not exist:\n" + "\n".join(unknown)


def test_the_check_finds_a_deleted_key(tmp_path, monkeypatch):
    page = tmp_path / "page.md"
    page.write_text("Run `pasta run task=crs execute.closed_loop=true` or set `planner.draws=sequence`.\n")
    monkeypatch.setattr(__import__(__name__), "DOCS", [page])
    monkeypatch.setattr(__import__(__name__), "ROOT", tmp_path)
    found = {key for _, _, key in _mentions()}
    assert {"execute.closed_loop", "planner.draws"} <= found
    assert "execute.closed_loop" not in valid_keys()["run"]
    with pytest.raises(AssertionError, match="execute.closed_loop"):
        test_docs_name_only_keys_that_exist()
