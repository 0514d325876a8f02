"""``key=value`` command-line arguments turned into typed dataclasses, for commands whose settings are
not part of the run config (``pasta demos``, ``pasta train``, ``pasta pipeline``, a command's own keys).

Values are converted by omegaconf from the dataclass field types, so errors read as they do for
:func:`pasta.config.load_config`; an unknown key names the closest valid one.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import fields
from typing import Any

from omegaconf import OmegaConf
from omegaconf.errors import OmegaConfBaseException

from pasta.core.errors import ConfigError, did_you_mean


def split_overrides(items: Sequence[str]) -> dict[str, str]:
    """``["a=1", "b=x"]`` -> ``{"a": "1", "b": "x"}``; a malformed item raises :class:`ConfigError`."""
    out: dict[str, str] = {}
    for item in items:
        key, eq, value = item.partition("=")
        if not eq or not key.strip():
            raise ConfigError(f"argument {item!r} must look like key=value")
        out[key.strip()] = value.strip()
    return out


def build(cls: type, values: Mapping[str, Any], *, command: str = "") -> Any:
    """An instance of dataclass ``cls`` with ``values`` (strings or typed) applied over its defaults."""
    known = [f.name for f in fields(cls)]
    for key in values:
        if key not in known:
            raise ConfigError(f"unknown key '{key}'{_for(command)}{did_you_mean(key, known)}; valid keys: {', '.join(known)}")
    try:
        node = OmegaConf.merge(OmegaConf.structured(cls), OmegaConf.from_dotlist([f"{k}={_text(v)}" for k, v in values.items()]))
        return OmegaConf.to_object(node)
    except OmegaConfBaseException as exc:
        raise ConfigError(f"{exc.full_key or 'argument'}{_for(command)}: {str(exc.msg).splitlines()[0]}") from None


def build_many(items: Sequence[str] | Mapping[str, Any], classes: Sequence[type], *, command: str = "") -> list[Any]:
    """Route each ``key=value`` to the first of ``classes`` (dataclasses) with that field; build them all."""
    values = split_overrides(items) if not isinstance(items, Mapping) else dict(items)
    routed: list[dict[str, Any]] = [{} for _ in classes]
    for key, value in values.items():
        owner = next((i for i, cls in enumerate(classes) if key in {f.name for f in fields(cls)}), None)
        if owner is None:
            known = [f.name for cls in classes for f in fields(cls)]
            raise ConfigError(f"unknown key '{key}'{_for(command)}{did_you_mean(key, known)}; valid keys: {', '.join(known)}")
        routed[owner][key] = value
    return [build(cls, v, command=command) for cls, v in zip(classes, routed)]


def _for(command: str) -> str:
    return f" for `{command}`" if command else ""


def _text(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    return "null" if value is None else str(value)


__all__ = ["build", "build_many", "split_overrides"]
