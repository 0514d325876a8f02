"""Run configuration: omegaconf structured configs, package YAML defaults, ``key=value`` overrides.

Group keys (:data:`GROUPS`) pick a registered plugin by name and swap in that plugin's config
dataclass as the whole section: ``planner=sampling planner.num_samples=2000``. Unknown keys and wrong
types fail with a :class:`~pasta.core.errors.ConfigError` naming the key and the closest valid key; values
are range-checked when the config is resolved (:func:`validate_config`: the seed, every ``device`` and
whatever each section's dataclass checks in its ``__post_init__``), so every command refuses the same
values before it computes anything.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass
from importlib import resources
from typing import Any

from omegaconf import DictConfig, OmegaConf
from omegaconf.errors import ConfigAttributeError, ConfigKeyError, OmegaConfBaseException, ValidationError

from pasta.core import PluginConfig
from pasta.core.errors import ConfigError, did_you_mean
from pasta.plugins.registry import GROUP_KINDS

#: config key -> plugin registry kind whose names it accepts
GROUPS: dict[str, str] = {kind: kind for kind in GROUP_KINDS}


@dataclass
class RunConfig:
    """Root of the run configuration. Group sections are typed ``Any`` and filled from the registries;
    each is a :class:`~pasta.core.PluginConfig` whose ``name`` is the chosen plugin."""

    seed: int = 0
    device: str = "cpu"
    planner: Any = None
    encoder: Any = None
    cost_model: Any = None


def default_yaml() -> dict[str, Any]:
    """The package's YAML defaults as a plain dict."""
    text = resources.files(__package__).joinpath("defaults.yaml").read_text()
    return OmegaConf.to_container(OmegaConf.create(text))  # type: ignore[return-value]


def load_config(overrides: Sequence[str] = (), *, plugins: Any = None) -> DictConfig:
    """Resolve the run config: dataclass schema <- package YAML <- group choices <- ``overrides``.

    Args:
        overrides: ``["key=value", ...]``; ``GROUP=NAME`` switches a group section.
        plugins: a :class:`pasta.plugins.Plugins` (default: the installed plugins).
    """
    if plugins is None:
        from pasta.plugins import get_plugins

        plugins = get_plugins()
    defaults = default_yaml()
    choices = {group: defaults.pop(group) for group in GROUPS if group in defaults}
    dotlist = []
    for item in overrides:
        key, eq, value = item.partition("=")
        key = key.strip()
        if not eq or not key:
            raise ConfigError(f"override {item!r} must look like key=value")
        if key in GROUPS:
            choices[key] = value.strip()
        elif key.split(".")[0] in GROUPS and key.endswith(".name"):
            raise ConfigError(f"'{key}' is set by the group switch; write {key.split('.')[0]}=NAME instead")
        else:
            dotlist.append(f"{key}={value}")

    cfg = OmegaConf.structured(RunConfig)
    for group, choice in choices.items():
        # a plugin without settings still records its name, so the section always says what was chosen
        chosen = plugins[GROUPS[group]].default_config(choice) or PluginConfig(name=choice)
        cfg = OmegaConf.merge(cfg, {group: OmegaConf.structured(chosen)})
    try:
        cfg = OmegaConf.merge(cfg, defaults, OmegaConf.from_dotlist(dotlist))
    except (ConfigKeyError, ConfigAttributeError) as exc:
        raise _unknown_key(cfg, exc) from None
    except ValidationError as exc:
        raise ConfigError(f"config key '{exc.full_key}': {str(exc.msg).splitlines()[0]}") from None
    except OmegaConfBaseException as exc:
        raise ConfigError(f"invalid config: {exc.msg}") from None
    validate_config(cfg)
    return cfg  # type: ignore[return-value]


def validate_config(cfg: DictConfig) -> None:
    """Range-check a resolved run config; raise a one-line :class:`ConfigError` naming the key.

    Checks ``seed`` (:func:`~pasta.config.validate.check_seed`), every ``device`` (top level and in each
    section; :func:`~pasta.config.validate.check_device`) and builds each group section's dataclass once,
    so its ``__post_init__`` checks (e.g. :class:`pasta.planning.LatentPlannerConfig`) run now.
    """
    from pasta.config.validate import check_device, check_seed

    check_seed(cfg.seed, "seed")
    check_device(cfg.device, "device")
    for group in GROUPS:
        node = cfg.get(group)
        if not isinstance(node, DictConfig):
            continue
        if "device" in node:
            check_device(node.device, f"{group}.device")
        try:
            OmegaConf.to_object(node)
        except ConfigError as exc:
            raise ConfigError(_prefixed(str(exc), group)) from None
        except OmegaConfBaseException as exc:
            raise ConfigError(f"config section '{group}': {str(exc.msg).splitlines()[0]}") from None


def section(cfg: DictConfig, key: str) -> Any:
    """The config section ``key`` as its dataclass instance (e.g. the chosen planner's config)."""
    return OmegaConf.to_object(cfg[key])


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
    valid = list(node.keys()) if isinstance(node, DictConfig) else []
    hint = did_you_mean(leaf, valid)
    where = f" under '{parent}'" if parent else ""
    prefix = f"{parent}." if parent else ""
    hint = hint.replace("'", f"'{prefix}", 1) if hint else ""
    return ConfigError(f"unknown config key '{full_key}'{hint}; valid keys{where}: {', '.join(map(str, valid))}")
