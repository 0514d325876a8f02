"""Run configuration: omegaconf structured configs, package YAML defaults, ``key=value`` overrides.

The schema is :class:`pasta.config.run.RunConfig`: every setting of a run, in one tree that ``pasta config``
prints. Group keys (:data:`GROUPS`) pick a registered plugin by name and swap in that plugin's config
dataclass as the whole section: ``planner=sampling planner.num_samples=2000``, ``task=crs_distractors
task.distractors=4``. A task may ask for run settings of its own (:attr:`pasta.core.Task.run_defaults`:
crs_twice plans with the receding-horizon planner and its ground-truth skeleton, as in the paper); they
sit under the command line. Every registered skill's settings are the section ``skill.<name>``.

Resolution order, later wins: the dataclass defaults <- ``defaults.yaml`` <- the chosen task's
``run_defaults`` <- ``key=value`` overrides. Unknown keys and wrong types fail with a
:class:`~pasta.core.errors.ConfigError` naming the key and the closest valid key; values are range-checked
when the config is resolved (:func:`validate_config`), so every command refuses the same values before it
computes anything.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from importlib import resources
from typing import Any, cast

from omegaconf import DictConfig, OmegaConf
from omegaconf.errors import ConfigAttributeError, ConfigKeyError, OmegaConfBaseException, ValidationError

from pasta.config.overrides import from_items
from pasta.config.run import METHODS, CheckConfig, ExecuteConfig, PerceptionConfig, RunConfig
from pasta.config.validate import check_literal
from pasta.config.validate import plain_type_message as _plain
from pasta.core import PluginConfig
from pasta.core.errors import ConfigError, did_you_mean

__all__ = ["GROUPS", "MAX_HORIZON", "CheckConfig", "ExecuteConfig", "PerceptionConfig", "RunConfig", "check_horizon",
           "default_yaml", "load_config", "section", "to_yaml", "validate_config"]

#: config key -> plugin registry kind whose names it accepts
GROUPS: dict[str, str] = {"planner": "planner", "encoder": "encoder", "cost_model": "cost_model", "task": "task"}
#: sections built from a dataclass of their own (checked by building them)
SECTIONS = ("perception", "check", "execute", "trajopt", "sim")
#: the deepest planning horizon a command accepts (``pasta plan``, ``pasta run``, ``pasta eval``): the skeleton
#: enumeration grows with K**H
MAX_HORIZON = 10


def check_horizon(value: Any) -> int | None:
    """``horizon=``: an integer in ``[1, MAX_HORIZON]``, or ``None`` (not given: the task's horizon, 3 for ``pasta
    plan``). ``horizon=0`` and ``horizon=`` are refused: omitting the key is the one way to ask for the default."""
    from pasta.config.validate import check_int

    if value is None:
        return None
    try:
        return check_int(value, "horizon", low=1, high=MAX_HORIZON)
    except ConfigError as exc:
        raise ConfigError(f"{exc} (omit horizon= for the task's horizon; pasta plan's is 3)") from None


def default_yaml() -> dict[str, Any]:
    """The package's YAML defaults as a plain dict."""
    text = resources.files(__package__).joinpath("defaults.yaml").read_text()
    return OmegaConf.to_container(OmegaConf.create(text))  # type: ignore[return-value]


def load_config(overrides: Sequence[str] = (), *, plugins: Any = None) -> DictConfig:
    """Resolve the run config (see the module docstring).

    Args:
        overrides: ``["key=value", ...]``; ``GROUP=NAME`` switches a group section.
        plugins: a :class:`pasta.plugins.Plugins` (default: the installed plugins).
    """
    if plugins is None:
        from pasta.plugins import get_plugins

        plugins = get_plugins()
    defaults = default_yaml()
    choices = {group: defaults.pop(group) for group in GROUPS if group in defaults}
    given: dict[str, str] = {}
    dotlist = []
    for item in overrides:
        key, eq, value = item.partition("=")
        key = key.strip()
        if not eq or not key:
            raise ConfigError(f"override {item!r} must look like key=value")
        check_literal(key, value)
        if key == "horizon":
            check_horizon(value.strip())
        if key in GROUPS:
            if not value.strip():
                kind = GROUPS[key]
                raise ConfigError(f"{key}=: names no {kind}; registered {kind}s: {', '.join(plugins[kind].names())} "
                                  f"(omit {key}= for {'no task' if key == 'task' else 'the default'})")
            given[key] = value.strip()
        elif key.split(".")[0] in GROUPS and key.endswith(".name"):
            raise ConfigError(f"'{key}' is set by the group switch; write {key.split('.')[0]}=NAME instead")
        else:  # an empty value is the empty string (`skeleton=`), not omegaconf's null
            dotlist.append(f"{key}={value}" if value.strip() else f"{key}=''")
    task_defaults: list[str] = []
    task = given.get("task") or choices.get("task")
    if task:
        # the task's own run settings (crs_twice: receding horizon and its skeleton) under the command line
        for key, value in dict(getattr(plugins.tasks.load(task), "run_defaults", {}) or {}).items():
            if key in GROUPS:
                choices[key] = value
            else:
                task_defaults.append(f"{key}={value}")
    choices.update(given)

    cfg = OmegaConf.structured(RunConfig)
    for group, choice in choices.items():
        if not choice:
            continue
        # a plugin without settings still records its name, so the section always says what was chosen
        chosen = plugins[GROUPS[group]].default_config(choice) or PluginConfig(name=choice)
        cfg = OmegaConf.merge(cfg, {group: OmegaConf.structured(chosen)})
    skills = {info.name: OmegaConf.structured(plugins.skills.default_config(info.name))
              for info in plugins.skills if info.config is not None}
    cfg = cast(DictConfig, OmegaConf.merge(cfg, {"skill": skills}))  # merging dict configs gives a dict config
    OmegaConf.set_struct(cfg, True)  # unknown keys anywhere are errors, with a suggestion
    OmegaConf.set_struct(cfg.sim.tool_friction, False)  # a mapping: any tool name (checked below)
    for item in dotlist:
        _check_leaf(cfg, item.partition("=")[0])
    try:
        cfg = cast(DictConfig, OmegaConf.merge(cfg, defaults, from_items(task_defaults), from_items(dotlist)))
    except (ConfigKeyError, ConfigAttributeError) as exc:
        raise _unknown_key(cfg, exc) from None
    except ValidationError as exc:
        given = {k.strip(): v for k, _, v in (i.partition("=") for i in overrides)}
        key = str(exc.full_key)
        shown = f"{key}={given[key]}" if key in given else f"config key '{key}'"
        raise ConfigError(f"{shown}: {_plain(str(exc.msg).splitlines()[0])}") from None
    except OmegaConfBaseException as exc:
        raise ConfigError(f"invalid config: {exc.msg}") from None
    validate_config(cfg, plugins=plugins)
    return cfg


def validate_config(cfg: DictConfig, *, plugins: Any = None) -> None:
    """Range-check a resolved run config; raise a one-line :class:`ConfigError` naming the key.

    Checks the top-level keys (seed, device, threads, method, horizon, the names in ``skills`` and
    ``skeleton``), builds every section's dataclass once, so its ``__post_init__`` checks run now, and
    checks that ``sim.tool_friction`` names registered tools.
    """
    from pasta.config.validate import check_choice, check_device, check_seed, check_threads

    check_seed(cfg.seed, "seed")
    check_device(cfg.device, "device")
    check_threads(cfg.threads, "threads")
    check_choice(cfg.method, "method", METHODS)
    if cfg.get("disturb"):
        from pasta.sim.disturb import DISTURBANCES

        check_choice(cfg.disturb, "disturb", DISTURBANCES)
    check_horizon(cfg.horizon)
    steps = split_names(cfg.skeleton, "skeleton")
    if steps and steps != ["task"] and cfg.horizon is not None and len(steps) != int(cfg.horizon):
        raise ConfigError(f"skeleton={cfg.skeleton} has {len(steps)} steps but horizon={cfg.horizon}: a given skeleton "
                          "sets the horizon (omit horizon=)")
    if plugins is not None:
        for key in ("skills", "skeleton"):
            for name in split_names(cfg[key], key):
                if not (key == "skeleton" and name == "task") and name not in plugins.skills:
                    known = plugins.skills.names()
                    raise ConfigError(f"{key}={cfg[key]}: '{name}' is not a registered skill{did_you_mean(name, known)}; "
                                      f"registered skills: {', '.join(known)}")
        if "task" in split_names(cfg.skeleton, "skeleton") and cfg.skeleton.strip() != "task":
            raise ConfigError(f"skeleton={cfg.skeleton}: 'task' (the task's ground-truth chain) stands alone")
        tools = plugins.tools.names()
        for tool in cfg.sim.tool_friction:
            if tool not in tools:
                raise ConfigError(f"sim.tool_friction.{tool}: no registered tool '{tool}'{did_you_mean(str(tool), tools)}; "
                                  f"registered tools: {', '.join(tools)}")
    for key in (*GROUPS, *SECTIONS):
        node = cfg.get(key)
        if not isinstance(node, DictConfig):
            continue
        if "device" in node:
            check_device(node.device, f"{key}.device")
        _build(node, key)
    for name, node in (cfg.get("skill") or {}).items():
        _build(node, f"skill.{name}")


def _check_leaf(cfg: DictConfig, key: str) -> None:
    """A ``key=value`` item sets one setting: a key that names a whole section (``execute=``, ``skill=x``,
    ``sim.tool_friction=``) is refused, naming the section's keys."""
    group = key.split(".")[0]
    if group in GROUPS and cfg.get(group) is None:
        kind = GROUPS[group]
        raise ConfigError(f"'{key}' is a setting of the chosen {kind}, and none is chosen; give {group}=NAME first")
    try:
        node = OmegaConf.select(cfg, key)
    except OmegaConfBaseException:
        return  # an unknown key: the merge names it, with the closest valid key
    if isinstance(node, DictConfig):
        inner = ", ".join(f"{key}.{k!s}" for k in node) or f"{key}.<name>"
        raise ConfigError(f"'{key}' is a section, not a setting; set its keys: {inner}")


def _build(node: DictConfig, key: str) -> Any:
    from pasta.config.validate import check_field_values

    try:
        return check_field_values(OmegaConf.to_object(node), f"{key}.")
    except ConfigError as exc:
        raise ConfigError(_prefixed(str(exc), key)) from None
    except OmegaConfBaseException as exc:
        raise ConfigError(f"config section '{key}': {str(exc.msg).splitlines()[0]}") from None
    except (TypeError, ValueError) as exc:  # a plugin dataclass whose own checks raise plain errors
        raise ConfigError(f"config section '{key}': {exc}") from None


def split_names(value: Any, key: str) -> list[str]:
    """``"cut,push"`` -> ``["cut", "push"]``; empty -> ``[]``."""
    return [n.strip() for n in str(value or "").split(",") if n.strip()]


def section(cfg: DictConfig, key: str) -> Any:
    """The config section ``key`` (``"planner"``, ``"execute"``, ``"skill.cut"``) as its dataclass instance."""
    node = OmegaConf.select(cfg, key)
    if node is None:
        raise ConfigError(f"the run config has no section '{key}'")
    return OmegaConf.to_object(node)


def to_yaml(cfg: DictConfig) -> str:
    return OmegaConf.to_yaml(cfg, resolve=True)


def _prefixed(message: str, group: str) -> str:
    """A section check that names only its field (``lr=nan: ...``) gets the section (``planner.lr=nan: ...``)."""
    if re.match(r"[A-Za-z_]\w*=", message) and not message.startswith(f"{group}."):
        return f"{group}.{message}"
    return f"config section '{group}': {message}" if not message.startswith(f"{group}.") else message


def _unknown_key(cfg: DictConfig, exc: OmegaConfBaseException) -> ConfigError:
    full_key = str(exc.full_key or "")
    parent, _, leaf = full_key.rpartition(".")
    node = OmegaConf.select(cfg, parent) if parent else cfg
    valid = [str(k) for k in node] if isinstance(node, DictConfig) else []
    hint = did_you_mean(leaf, valid)
    where = f" under '{parent}'" if parent else ""
    prefix = f"{parent}." if parent else ""
    hint = hint.replace("'", f"'{prefix}", 1) if hint else ""
    return ConfigError(f"unknown config key '{full_key}'{hint}; valid keys{where}: {', '.join(map(str, valid))}")
