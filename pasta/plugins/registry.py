"""Plugin discovery (entry points through pluggy) and the registries queried by name.

Every plugin, built-in or third-party, is a module named by an entry point in the ``pasta.plugins``
group; the built-ins are declared in pasta's own ``pyproject.toml`` and load through the same path. A
plugin that fails to import is reported with its name and distribution, and the others still load.
"""

from __future__ import annotations

import importlib
import importlib.metadata as metadata
import warnings
from collections.abc import Iterator
from dataclasses import dataclass, field, is_dataclass
from typing import Any

import pluggy

from pasta.core import CostModel, Encoder, Planner, PluginConfig, Skill, SkillSpec
from pasta.core.errors import PluginNotFoundError, PluginValidationError
from pasta.plugins import hookspecs

ENTRY_POINT_GROUP = "pasta.plugins"

#: registry kind -> (hook name, base class the factory must subclass or None)
KINDS: dict[str, tuple[str, type | None]] = {
    "skill": ("pasta_register_skills", Skill),
    "planner": ("pasta_register_planners", Planner),
    "encoder": ("pasta_register_encoders", Encoder),
    "cost_model": ("pasta_register_cost_models", CostModel),
    "task": ("pasta_register_tasks", None),
}


#: kinds chosen by a config group switch (``planner=NAME``); their configs carry the chosen ``name``
GROUP_KINDS = ("planner", "encoder", "cost_model")


class PluginLoadWarning(UserWarning):
    """A plugin could not be imported or registered; the other plugins were loaded."""


@dataclass(frozen=True)
class PluginInfo:
    """One registered component, known without importing its implementation.

    Attributes:
        kind: ``"skill"``, ``"planner"``, ``"encoder"``, ``"cost_model"`` or ``"task"``.
        name: registry name.
        factory: ``"module:attribute"`` of the class (or callable) that builds it.
        config: the component's config dataclass, or ``None``.
        summary: one line for listings.
        spec: a skill's :class:`SkillSpec` (skills only).
        plugin: entry-point name of the plugin that registered it.
        distribution, version: the installed distribution that declared the plugin.
    """

    kind: str
    name: str
    factory: str
    config: type | None = None
    summary: str = ""
    spec: SkillSpec | None = None
    plugin: str = ""
    distribution: str = ""
    version: str = ""

    def load(self) -> Any:
        """Import and return the factory, checking it honours the contract of its kind."""
        module_name, _, attr = self.factory.partition(":")
        try:
            obj = getattr(importlib.import_module(module_name), attr) if attr else importlib.import_module(module_name)
        except (ImportError, AttributeError) as exc:
            raise PluginValidationError(
                f"{self.kind} '{self.name}' (plugin '{self.plugin}' from {self.distribution or 'unknown distribution'}): "
                f"cannot import factory '{self.factory}': {exc}"
            ) from exc
        base = KINDS[self.kind][1]
        if base is not None and not (isinstance(obj, type) and issubclass(obj, base)):
            raise PluginValidationError(f"{self.kind} '{self.name}': factory '{self.factory}' is not a {base.__name__} subclass")
        if self.kind == "skill" and getattr(obj, "spec", None) != self.spec:
            raise PluginValidationError(
                f"skill '{self.name}': {self.factory}.spec = {getattr(obj, 'spec', None)} differs from the registered {self.spec}"
            )
        return obj


@dataclass(frozen=True)
class PluginFailure:
    """A plugin that could not be loaded."""

    plugin: str
    distribution: str
    error: str


class Registry:
    """The components of one kind, by name."""

    def __init__(self, kind: str, entries: dict[str, PluginInfo]) -> None:
        self.kind = kind
        self._entries = dict(sorted(entries.items()))

    def names(self) -> list[str]:
        return list(self._entries)

    def info(self, name: str) -> PluginInfo:
        """The registration of ``name``; an unknown name raises an error listing the known ones."""
        try:
            return self._entries[name]
        except KeyError:
            raise PluginNotFoundError(self.kind, name, self._entries) from None

    def load(self, name: str) -> Any:
        """Import and return the factory of ``name`` (a class)."""
        return self.info(name).load()

    def default_config(self, name: str) -> Any:
        """A fresh default config instance for ``name`` (``None`` if it has no config)."""
        info = self.info(name)
        if info.config is None:
            return None
        cfg = info.config()
        if isinstance(cfg, PluginConfig):
            cfg.name = name
        return cfg

    def create(self, name: str, config: Any = None, **kwargs: Any) -> Any:
        """Build ``name`` with ``config`` (defaults when ``None``) and extra keyword arguments."""
        factory = self.load(name)
        return factory(self.default_config(name) if config is None else config, **kwargs)

    def __contains__(self, name: object) -> bool:
        return name in self._entries

    def __iter__(self) -> Iterator[PluginInfo]:
        return iter(self._entries.values())

    def __len__(self) -> int:
        return len(self._entries)


@dataclass
class Plugins:
    """All registries plus the plugins that failed to load."""

    registries: dict[str, Registry]
    failures: list[PluginFailure] = field(default_factory=list)

    def __getitem__(self, kind: str) -> Registry:
        if kind not in self.registries:
            raise PluginNotFoundError("plugin kind", kind, self.registries)
        return self.registries[kind]

    @property
    def skills(self) -> Registry:
        return self.registries["skill"]

    @property
    def planners(self) -> Registry:
        return self.registries["planner"]

    @property
    def encoders(self) -> Registry:
        return self.registries["encoder"]

    @property
    def cost_models(self) -> Registry:
        return self.registries["cost_model"]

    @property
    def tasks(self) -> Registry:
        return self.registries["task"]


def discover(group: str = ENTRY_POINT_GROUP, extra: dict[str, Any] | None = None) -> Plugins:
    """Load every plugin of the entry-point ``group`` (plus ``extra`` in-process plugin objects by name).

    Plugins that fail to import or register are reported with a :class:`PluginLoadWarning` and listed in
    :attr:`Plugins.failures`; the others load.
    """
    pm = pluggy.PluginManager(hookspecs.PROJECT)
    pm.add_hookspecs(hookspecs)
    origin: dict[str, tuple[str, str]] = {}
    failures: list[PluginFailure] = []
    eps = sorted(metadata.entry_points(group=group), key=lambda e: (e.name, _dist_name(e)))
    for ep in eps:
        dist, version = _dist_name(ep), _dist_version(ep)
        if pm.has_plugin(ep.name):
            _fail(failures, ep.name, dist, f"another plugin named '{ep.name}' is already loaded (from {origin[ep.name][0]})")
            continue
        try:
            pm.register(ep.load(), name=ep.name)
            pm.check_pending()  # a hook implementation without a spec (a misspelled hook name) fails here
        except Exception as exc:  # noqa: BLE001 - any import-time failure of a third-party plugin
            if pm.has_plugin(ep.name):
                pm.unregister(name=ep.name)
            _fail(failures, ep.name, dist, f"{type(exc).__name__}: {exc}")
            continue
        origin[ep.name] = (dist, version)
    for name, obj in (extra or {}).items():
        pm.register(obj, name=name)
        origin[name] = ("(in-process)", "")

    entries: dict[str, dict[str, PluginInfo]] = {kind: {} for kind in KINDS}
    for plugin_name, plugin in pm.list_name_plugin():
        dist, version = origin.get(plugin_name, ("(unknown)", ""))
        others = [p for n, p in pm.list_name_plugin() if n != plugin_name]  # call this plugin's hooks alone
        for kind, (hook_name, _) in KINDS.items():
            caller = pm.subset_hook_caller(hook_name, remove_plugins=others)
            register = _registrar(kind, entries[kind], failures, plugin_name, dist, version)
            try:
                caller(register=register)
            except Exception as exc:  # noqa: BLE001 - a faulty registration must not hide the others
                _fail(failures, plugin_name, dist, f"{hook_name} failed: {type(exc).__name__}: {exc}")
    return Plugins({kind: Registry(kind, e) for kind, e in entries.items()}, failures)


def _registrar(kind: str, into: dict[str, PluginInfo], failures: list[PluginFailure], plugin: str, dist: str, version: str):
    def register(*, factory: str, name: str | None = None, spec: SkillSpec | None = None, config: type | None = None, summary: str = "") -> None:
        if kind == "skill":
            if not isinstance(spec, SkillSpec):
                raise PluginValidationError(f"plugin '{plugin}': register a skill with spec=SkillSpec(...), got {spec!r}")
            name = spec.name
        if not name or not isinstance(factory, str) or ":" not in factory:
            raise PluginValidationError(f"plugin '{plugin}': {kind} needs a name and a factory 'module:attribute', got {name!r}, {factory!r}")
        if config is not None and not (isinstance(config, type) and is_dataclass(config)):
            raise PluginValidationError(f"plugin '{plugin}': {kind} '{name}' config must be a dataclass type, got {config!r}")
        if kind == "planner" and config is None:
            raise PluginValidationError(f"plugin '{plugin}': planner '{name}' needs a config (a pasta.core.PluginConfig subclass)")
        if kind in GROUP_KINDS and config is not None and not issubclass(config, PluginConfig):
            raise PluginValidationError(f"plugin '{plugin}': {kind} '{name}' config must subclass pasta.core.PluginConfig")
        if name in into:
            first = into[name]
            _fail(failures, plugin, dist, f"{kind} '{name}' is already registered by plugin '{first.plugin}' ({first.distribution}); kept that one")
            return
        into[name] = PluginInfo(kind, name, factory, config, summary or (spec.description if spec else ""), spec, plugin, dist, version)

    return register


def _fail(failures: list[PluginFailure], plugin: str, dist: str, error: str) -> None:
    failures.append(PluginFailure(plugin, dist, error))
    warnings.warn(f"pasta plugin '{plugin}' from distribution '{dist}': {error}", PluginLoadWarning, stacklevel=3)


def _dist_name(ep: metadata.EntryPoint) -> str:
    return ep.dist.metadata["Name"] if ep.dist is not None else "(unknown)"


def _dist_version(ep: metadata.EntryPoint) -> str:
    return ep.dist.version if ep.dist is not None else ""


_cache: Plugins | None = None


def get_plugins(refresh: bool = False) -> Plugins:
    """The process-wide plugin set, discovered once; ``refresh=True`` rescans the entry points."""
    global _cache
    if refresh or _cache is None:
        importlib.invalidate_caches()
        _cache = discover()
    return _cache
