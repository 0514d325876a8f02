"""Plugin machinery: hook specifications, entry-point discovery and registries by name.

Typical use::

    from pasta.plugins import get_plugins
    plugins = get_plugins()
    planner = plugins.planners.create("exhaustive")
    cut = plugins.skills.create("cut")
    knife = plugins.tools.spec("knife")        # tools are data: a pasta.core.ToolSpec
    plugins.failures                           # plugins or components refused at load time

Plugin authors implement the hooks of :mod:`pasta.plugins.hookspecs` with :data:`hookimpl`, check their
work with :mod:`pasta.plugins.checks`, and reuse the contract tests of :mod:`pasta.plugins.testing`.
"""

from pasta.plugins.hookspecs import hookimpl, hookspec
from pasta.plugins.registry import (
    ENTRY_POINT_GROUP,
    PluginFailure,
    PluginInfo,
    PluginLoadWarning,
    Plugins,
    Registry,
    discover,
    get_plugins,
)

__all__ = [
    "ENTRY_POINT_GROUP",
    "PluginFailure",
    "PluginInfo",
    "PluginLoadWarning",
    "Plugins",
    "Registry",
    "discover",
    "get_plugins",
    "hookimpl",
    "hookspec",
]
