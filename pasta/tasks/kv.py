"""``key=value`` command-line arguments parsed into a typed dataclass (used by ``pasta demos`` and
``pasta oracle``). Unknown keys and bad values fail with a message naming the key and the valid ones."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import fields
from typing import Any, TypeVar

from pasta.core.errors import ConfigError, did_you_mean

T = TypeVar("T")


def parse_kv(cls: type[T], items: Sequence[str], command: str) -> T:
    """Build ``cls`` (a dataclass) from ``["key=value", ...]``; ints, floats, bools and strings."""
    types = {f.name: f.type for f in fields(cls)}
    values: dict[str, Any] = {}
    for item in items:
        key, eq, raw = item.partition("=")
        key = key.strip()
        if not eq or not key:
            raise ConfigError(f"argument {item!r} must look like key=value (keys: {', '.join(types)})")
        if key not in types:
            raise ConfigError(f"unknown argument '{key}'{did_you_mean(key, types)}; {command} takes: {', '.join(types)}")
        values[key] = _convert(key, raw.strip(), str(types[key]))
    return cls(**values)


def _convert(key: str, raw: str, type_name: str) -> Any:
    base = type_name.replace("| None", "").replace("Optional[", "").replace("]", "").strip()
    if raw.lower() in ("none", "null") and "None" in type_name:
        return None
    try:
        if base == "int":
            return int(raw)
        if base == "float":
            return float(raw)
        if base == "bool":
            if raw.lower() in ("1", "true", "yes", "on"):
                return True
            if raw.lower() in ("0", "false", "no", "off"):
                return False
            raise ValueError(raw)
    except ValueError:
        raise ConfigError(f"argument '{key}={raw}': expected {base}") from None
    return raw
