"""Plugin discovery (entry points through pluggy) and the registries queried by name.

Every plugin, built-in or third-party, is a module named by an entry point in the ``pasta.plugins``
group; the built-ins are declared in pasta's own ``pyproject.toml`` and load through the same path. A
plugin that fails to import, and a component refused by the load-time rules (a name another plugin
registered, a skill whose tool is not registered; see :func:`discover`), is reported once per command
with its name and distribution (:func:`get_plugins`), and the others still load.
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.metadata as metadata
import os
import warnings
from collections.abc import Iterator
from dataclasses import dataclass, field, is_dataclass
from typing import Any

import pluggy

from pasta.core import CostModel, Encoder, Planner, PluginConfig, Skill, SkillSpec, Task, ToolSpec
from pasta.core.errors import PluginNotFoundError, PluginValidationError
from pasta.plugins import hookspecs

ENTRY_POINT_GROUP = "pasta.plugins"
#: the distribution that ships the built-in plugins; on a name clash its registration is kept
BUILTIN_DISTRIBUTION = "pasta-dough"
#: distribution name shown for plugins passed to :func:`discover` as ``extra`` objects
IN_PROCESS = "(in-process)"

#: registry kind -> (hook name, base class the factory must subclass or None)
KINDS: dict[str, tuple[str, type | None]] = {
    "skill": ("pasta_register_skills", Skill),
    "tool": ("pasta_register_tools", None),
    "planner": ("pasta_register_planners", Planner),
    "encoder": ("pasta_register_encoders", Encoder),
    "cost_model": ("pasta_register_cost_models", CostModel),
    "task": ("pasta_register_tasks", Task),
}

#: kinds registered as plain data (a spec, no factory to import)
DATA_KINDS = ("tool",)

#: kinds chosen by a config group switch (``planner=NAME``); their configs carry the chosen ``name``
GROUP_KINDS = ("planner", "encoder", "cost_model", "task")


class PluginLoadWarning(UserWarning):
    """A plugin could not be imported or registered; the other plugins were loaded."""


@dataclass(frozen=True)
class PluginInfo:
    """One registered component, known without importing its implementation.

    Attributes:
        kind: ``"skill"``, ``"tool"``, ``"planner"``, ``"encoder"``, ``"cost_model"`` or ``"task"``.
        name: registry name.
        factory: ``"module:attribute"`` of the class (or callable) that builds it; ``""`` for data kinds
            (tools), which are fully described by ``spec``.
        config: the component's config dataclass, or ``None``.
        summary: one line for listings.
        spec: a skill's :class:`SkillSpec` or a tool's :class:`~pasta.core.ToolSpec` (``None`` otherwise).
        plugin: entry-point name of the plugin that registered it.
        distribution, version: the installed distribution that declared the plugin.
    """

    kind: str
    name: str
    factory: str = ""
    config: type | None = None
    summary: str = ""
    spec: Any = None
    plugin: str = ""
    distribution: str = ""
    version: str = ""

    @property
    def origin(self) -> str:
        """``plugin 'NAME' from DISTRIBUTION VERSION``, for messages."""
        version = f" {self.version}" if self.version else ""
        return f"plugin '{self.plugin}' from {self.distribution or 'an unknown distribution'}{version}"

    def load(self) -> Any:
        """Import and return the factory, checking it honours the contract of its kind."""
        if self.kind in DATA_KINDS:
            raise PluginValidationError(f"{self.kind} '{self.name}' is data, not a class: read its spec ({self.spec!r})")
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
            raise PluginValidationError(
                f"{self.kind} '{self.name}': factory '{self.factory}' is not a pasta.core.{base.__name__} subclass"
            )
        if self.kind == "skill" and getattr(obj, "spec", None) != self.spec:
            raise PluginValidationError(
                f"skill '{self.name}': {self.factory}.spec = {getattr(obj, 'spec', None)} differs from the registered {self.spec}"
            )
        if self.kind == "task" and getattr(obj, "name", None) != self.name:
            raise PluginValidationError(
                f"task '{self.name}': {self.factory}.name = {getattr(obj, 'name', None)!r} differs from the registered name"
            )
        return obj


@dataclass(frozen=True)
class PluginFailure:
    """A plugin, or one component it registered, that could not be loaded.

    Attributes:
        plugin, distribution: the entry point and the distribution that declared it.
        error: what went wrong and what to do about it.
        kind, name: the component that was refused (``""`` when the whole plugin failed to load).
    """

    plugin: str
    distribution: str
    error: str
    kind: str = ""
    name: str = ""

    def message(self) -> str:
        """One line: ``pasta plugin 'P' from distribution 'D': ERROR``."""
        return f"pasta plugin '{self.plugin}' from distribution '{self.distribution}': {self.error}"


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

    def spec(self, name: str) -> Any:
        """The registered spec of ``name``: a :class:`SkillSpec` (skills) or :class:`~pasta.core.ToolSpec` (tools)."""
        return self.info(name).spec

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
    def tools(self) -> Registry:
        """Simulator tools (data: ``tools.spec(name)`` is the :class:`~pasta.core.ToolSpec`)."""
        return self.registries["tool"]

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

    def simulated_tools(self) -> list[ToolSpec]:
        """Every registered tool that has geometry (what a ``pasta.sim.Simulator`` can hold), in registry order."""
        return [info.spec for info in self.tools if info.spec.simulated]


def discover(group: str = ENTRY_POINT_GROUP, extra: dict[str, Any] | None = None) -> Plugins:
    """Load every plugin of the entry-point ``group`` (plus ``extra`` in-process plugin objects by name).

    Plugins that fail to import or register, and components refused by the rules below, are listed in
    :attr:`Plugins.failures` (reported once per process by :func:`get_plugins`); the others load.

    Rules, checked here so that nothing fails after work began:

    - **Names.** Entry-point names only label a plugin inside its distribution (two distributions may
      both have an entry point ``cut``). Component names are global per kind: when two plugins register
      the same skill, tool, planner, encoder, cost model or task name, the registration of the built-in
      distribution (:data:`BUILTIN_DISTRIBUTION`) is kept and the other is refused; between plugins of
      other distributions none is kept. Either way every refused registration is a failure naming both
      distributions, so a package can never displace a built-in, or another package, silently.
    - **Tools.** A skill whose ``spec.tool``, or a static tool its ``spec.needs`` names, is not a registered
      tool is refused; the failure lists the known tools.
    """
    pm = pluggy.PluginManager(hookspecs.PROJECT)
    pm.add_hookspecs(hookspecs)
    origin: dict[str, tuple[str, str, str]] = {}  # pluggy name -> (entry-point name, distribution, version)
    failures: list[PluginFailure] = []
    # the built-in distribution first, so that its plugins are listed (and kept on a clash) first
    eps = sorted(metadata.entry_points(group=group), key=lambda e: (_dist_name(e) != BUILTIN_DISTRIBUTION, _dist_name(e), e.name))
    for ep in eps:
        dist, version = _dist_name(ep), _dist_version(ep)
        key = f"{dist}:{ep.name}"
        if pm.has_plugin(key):  # the same distribution seen twice on sys.path: importlib already dedups, be safe
            continue
        try:
            pm.register(ep.load(), name=key)
            pm.check_pending()  # a hook implementation without a spec (a misspelled hook name) fails here
        except Exception as exc:  # noqa: BLE001 - any import-time failure of a third-party plugin
            if pm.has_plugin(key):
                pm.unregister(name=key)
            failures.append(PluginFailure(ep.name, dist, f"{type(exc).__name__}: {exc}"))
            continue
        origin[key] = (ep.name, dist, version)
    for name, obj in (extra or {}).items():
        key = f"{IN_PROCESS}:{name}"
        pm.register(obj, name=key)
        origin[key] = (name, IN_PROCESS, "")

    candidates: dict[str, dict[str, list[PluginInfo]]] = {kind: {} for kind in KINDS}
    for key, _plugin in pm.list_name_plugin():
        plugin_name, dist, version = origin.get(key, (key, "(unknown)", ""))
        others = [p for n, p in pm.list_name_plugin() if n != key]  # call this plugin's hooks alone
        for kind, (hook_name, _) in KINDS.items():
            caller = pm.subset_hook_caller(hook_name, remove_plugins=others)
            register = _registrar(kind, candidates[kind], plugin_name, dist, version)
            try:
                caller(register=register)
            except Exception as exc:  # noqa: BLE001 - a faulty registration must not hide the others
                failures.append(PluginFailure(plugin_name, dist, f"{hook_name} failed: {type(exc).__name__}: {exc}"))
    entries = {kind: _resolve_clashes(kind, by_name, failures) for kind, by_name in candidates.items()}
    _check_skill_tools(entries["skill"], entries["tool"], failures)
    return Plugins({kind: Registry(kind, e) for kind, e in entries.items()}, failures)


def _registrar(kind: str, into: dict[str, list[PluginInfo]], plugin: str, dist: str, version: str):
    def register(*, factory: str | None = None, name: str | None = None, spec: Any = None, config: type | None = None,
                 summary: str = "") -> None:
        if kind == "skill":
            if not isinstance(spec, SkillSpec):
                raise PluginValidationError(f"plugin '{plugin}': register a skill with spec=SkillSpec(...), got {spec!r}")
            name = spec.name
        elif kind == "tool":
            if not isinstance(spec, ToolSpec) or factory is not None:
                raise PluginValidationError(
                    f"plugin '{plugin}': register a tool with spec=ToolSpec(...) only (tools are data), got spec={spec!r}, "
                    f"factory={factory!r}"
                )
            name = spec.name
        if kind not in DATA_KINDS and (not name or not isinstance(factory, str) or ":" not in factory):
            raise PluginValidationError(f"plugin '{plugin}': {kind} needs a name and a factory 'module:attribute', got {name!r}, {factory!r}")
        if config is not None and not (isinstance(config, type) and is_dataclass(config)):
            raise PluginValidationError(f"plugin '{plugin}': {kind} '{name}' config must be a dataclass type, got {config!r}")
        if kind == "planner" and config is None:
            raise PluginValidationError(f"plugin '{plugin}': planner '{name}' needs a config (a pasta.core.PluginConfig subclass)")
        if kind in GROUP_KINDS and config is not None and not issubclass(config, PluginConfig):
            raise PluginValidationError(f"plugin '{plugin}': {kind} '{name}' config must subclass pasta.core.PluginConfig")
        description = getattr(spec, "description", "") if spec is not None else ""
        into.setdefault(str(name), []).append(
            PluginInfo(kind, str(name), factory or "", config, summary or description, spec, plugin, dist, version))

    return register


def _resolve_clashes(kind: str, by_name: dict[str, list[PluginInfo]], failures: list[PluginFailure]) -> dict[str, PluginInfo]:
    """One registration per name (see the rules of :func:`discover`); refused ones become failures."""
    kept: dict[str, PluginInfo] = {}
    for name, infos in by_name.items():
        if len(infos) == 1:
            kept[name] = infos[0]
            continue
        builtins = [i for i in infos if i.distribution == BUILTIN_DISTRIBUTION]
        if builtins:
            winner = kept[name] = builtins[0]
            for info in infos:
                if info is not winner:
                    failures.append(PluginFailure(info.plugin, info.distribution, (
                        f"{kind} '{name}' is already registered by the built-in {winner.origin}; the built-in is kept "
                        f"and this registration is ignored: give yours another name"), kind, name))
            continue
        for info in infos:
            rivals = "; ".join(other.origin for other in infos if other is not info)
            failures.append(PluginFailure(info.plugin, info.distribution, (
                f"{kind} '{name}' is also registered by {rivals}; none of them is loaded: uninstall one of the "
                f"distributions or rename the {kind}"), kind, name))
    return kept


def _check_skill_tools(skills: dict[str, PluginInfo], tools: dict[str, PluginInfo], failures: list[PluginFailure]) -> None:
    """Refuse skills whose tool no plugin registers (they would fail only once execution began)."""
    known = ", ".join(sorted(tools)) or "(none registered)"
    for name, info in list(skills.items()):
        tool = info.spec.tool
        if tool not in tools:
            del skills[name]
            failures.append(PluginFailure(info.plugin, info.distribution, (
                f"skill '{name}' drives tool '{tool}', which no plugin registers; known tools: {known}. "
                f"Register it with the pasta_register_tools hook"), "skill", name))
            continue
        missing = [t for t in info.spec.needs.static if t not in tools]
        if missing:  # no scene could ever stand it: the skill would silently never be planned
            del skills[name]
            failures.append(PluginFailure(info.plugin, info.distribution, (
                f"skill '{name}' needs the static tool{'s' if len(missing) > 1 else ''} {', '.join(missing)} "
                f"(SkillSpec.needs), which no plugin registers; known tools: {known}"), "skill", name))


def _dist_name(ep: metadata.EntryPoint) -> str:
    return ep.dist.metadata["Name"] if ep.dist is not None else "(unknown)"


def _dist_version(ep: metadata.EntryPoint) -> str:
    return ep.dist.version if ep.dist is not None else ""


_cache: Plugins | None = None
#: failures already reported (:meth:`PluginFailure.message`), so each prints once per command
_reported: set[str] = set()
#: child processes (``spawn`` workers of ``pasta demos``) inherit the digests of the failures their parent
#: reported through this variable and stay quiet about them
_REPORTED_ENV = "PASTA_PLUGIN_FAILURES_REPORTED"


def get_plugins(refresh: bool = False, *, report: bool = True) -> Plugins:
    """The process-wide plugin set, discovered once; ``refresh=True`` rescans the entry points.

    With ``report`` each failure is issued once per command as a :class:`PluginLoadWarning` (the CLI prints
    it as one ``warning: pasta plugin ...`` line); ``pasta plugins`` passes ``report=False`` and lists them itself.
    """
    global _cache
    if refresh or _cache is None:
        importlib.invalidate_caches()
        if refresh:  # an explicit rescan reports what it finds again
            _reported.clear()
            os.environ.pop(_REPORTED_ENV, None)
        _cache = discover()
    if report:
        report_failures(_cache.failures)
    return _cache


def report_failures(failures: list[PluginFailure]) -> None:
    """Warn (:class:`PluginLoadWarning`) about each failure not reported yet in this command."""
    inherited = set(filter(None, os.environ.get(_REPORTED_ENV, "").split(",")))
    for failure in failures:
        message = failure.message()
        digest = hashlib.sha1(message.encode()).hexdigest()[:12]
        if message in _reported or digest in inherited:
            continue
        _reported.add(message)
        inherited.add(digest)
        warnings.warn(message, PluginLoadWarning, stacklevel=3)
    if inherited:
        os.environ[_REPORTED_ENV] = ",".join(sorted(inherited))
