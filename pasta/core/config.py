"""Base class of plugin configuration sections."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class PluginConfig:
    """Base of a plugin's config dataclass, for sections chosen by a group switch (``planner=sampling``).

    ``name`` is filled with the chosen plugin's registry name when the config is resolved.
    """

    name: str = ""
