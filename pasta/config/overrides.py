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


def from_items(items: Sequence[str]) -> Any:
    """``["a.b=1", "c=x"]`` as an omegaconf config (values read as YAML scalars, as omegaconf reads them; a later
    item of the same key wins). A value that YAML cannot read (``"``, ``{``, control characters) raises a
    one-line :class:`ConfigError` naming its item."""
    import yaml

    parts = []
    for item in items:
        try:
            parts.append(OmegaConf.from_dotlist([item]))
        except (yaml.YAMLError, ValueError) as exc:
            key, _, value = item.partition("=")
            why = str(getattr(exc, "problem", "") or exc).splitlines()[0]
            raise ConfigError(f"{key}={value}: cannot be read as a value ({why}); quote it for YAML, "
                              f"e.g. {key}='text'") from None
    return OmegaConf.merge(*parts) if parts else OmegaConf.create()


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
    """An instance of dataclass ``cls`` with ``values`` (strings or typed) applied over its defaults.

    Every value is checked here, before the command does any work: its type (omegaconf, from the field's
    annotation), no ``${...}`` interpolation, finite floats and 64-bit integers in every field
    (:func:`~pasta.config.validate.check_field_values`), and the dataclass's own ``__post_init__`` checks.
    """
    from pasta.config.validate import check_field_values, check_literal, plain_type_message

    known = [f.name for f in fields(cls)]
    for key, value in values.items():
        if key not in known:
            raise ConfigError(f"unknown key '{key}'{_for(command)}{did_you_mean(key, known)}; valid keys: {', '.join(known)}")
        check_literal(key, _text(value))
    dotlist = [f"{k}={_text(v)}" if _text(v).strip() else f"{k}=''" for k, v in values.items()]
    try:
        node = OmegaConf.merge(OmegaConf.structured(cls), from_items(dotlist))
        return check_field_values(OmegaConf.to_object(node))
    except ConfigError:
        raise
    except OmegaConfBaseException as exc:
        key = str(exc.full_key or "")
        shown = f"{key}={_text(values[key])}" if key in values else (key or "argument")
        raise ConfigError(f"{shown}{_for(command)}: {plain_type_message(str(exc.msg).splitlines()[0])}") from None
    except (TypeError, ValueError) as exc:  # a dataclass whose own checks raise plain errors
        raise ConfigError(f"{cls.__name__}{_for(command)}: {exc}") from None


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


__all__ = ["build", "build_many", "from_items", "split_overrides"]
