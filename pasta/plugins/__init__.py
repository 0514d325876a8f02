"""Plugin machinery: hook specifications, entry-point discovery and registries by name.

Typical use::

    from pasta.plugins import get_plugins
    plugins = get_plugins()
    planner = plugins.planners.create("exhaustive")
    cut = plugins.skills.create("cut")
    knife = plugins.tools.spec("knife")        # tools are data: a pasta.core.ToolSpec
    plugins.failures                           # plugins or components refused at load time

Plugin authors implement the hooks of :mod:`pasta.plugins.hookspecs` with :data:`hookimpl` and test their
plugins with :mod:`pasta.testing` (contract suites, conformance checkers, an analytic problem). This package
holds only the hook specifications and the registry: it imports nothing of pasta but :mod:`pasta.core`.
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
