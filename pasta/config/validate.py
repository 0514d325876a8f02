"""Value checks shared by every command: seeds, thread counts, torch devices, numeric ranges, output paths.

Each ``check_*`` returns the value in its proper type or raises a one-line
:class:`~pasta.core.errors.ConfigError` that names the key, the value given and what is allowed, so the
CLI prints it and exits with code 2 instead of a traceback. Checks run before anything is computed:
a bad ``out=`` must not cost a finished plan.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from pasta.core.errors import ConfigError, did_you_mean

#: Seeds are integers in [0, SEED_MAX]: numpy's legacy ``RandomState`` and scikit-learn's ``random_state``
#: accept 32-bit seeds, and derived seeds (``seed + i``) then still fit torch's 64-bit ``manual_seed``.
SEED_MAX = 2**32 - 1


def check_seed(value: Any, key: str = "seed") -> int:
    """``value`` as an int in ``[0, SEED_MAX]``."""
    seed = _as_int(value, key, f"an integer in [0, {SEED_MAX}]")
    if not 0 <= seed <= SEED_MAX:
        raise ConfigError(f"{key}={_show(value)}: must be an integer in [0, {SEED_MAX}] (32-bit seeds, as numpy and "
                          "scikit-learn accept)")
    return seed


#: more threads than this is a typo, not a machine (torch and Taichi would try to start them all)
MAX_THREADS = 1024


def check_threads(value: Any, key: str = "threads") -> int:
    """A CPU thread count in ``[0, MAX_THREADS]`` (0: leave the library's default)."""
    allowed = f"an integer in [0, {MAX_THREADS}] (0: the library's default)"
    threads = _as_int(value, key, allowed)
    if not 0 <= threads <= MAX_THREADS:
        raise ConfigError(f"{key}={_show(value)}: must be {allowed}")
    return threads


def check_int(value: Any, key: str, *, low: int | None = None, high: int | None = None) -> int:
    """``value`` as an int in ``[low, high]`` (either bound optional)."""
    allowed = _range_text(low, high, integer=True)
    n = _as_int(value, key, allowed)
    if (low is not None and n < low) or (high is not None and n > high):
        raise ConfigError(f"{key}={_show(value)}: must be {allowed}")
    return n


def check_number(value: Any, key: str, *, low: float | None = None, high: float | None = None,
                 low_open: bool = False, high_open: bool = False) -> float:
    """``value`` as a finite float in the interval given (``low_open``: ``> low`` instead of ``>= low``)."""
    allowed = _range_text(low, high, low_open=low_open, high_open=high_open)
    if isinstance(value, bool):
        raise ConfigError(f"{key}={_show(value)}: must be {allowed}")
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ConfigError(f"{key}={_show(value)}: must be {allowed}") from None
    ok = math.isfinite(x)
    if ok and low is not None:
        ok = x > low if low_open else x >= low
    if ok and high is not None:
        ok = x < high if high_open else x <= high
    if not ok:
        raise ConfigError(f"{key}={_show(value)}: must be {allowed}")
    return x


def check_ranges(obj: Any, ranges: dict[str, tuple], prefix: str = "") -> None:
    """Range-check fields of dataclass ``obj``: ``{field: (low, high)}`` or ``(low, high, "(]")`` (the
    brackets say which ends are open; either bound ``None``). Integer fields go through :func:`check_int`,
    the others through :func:`check_number` (finite)."""
    for name, bounds in ranges.items():
        low, high = bounds[0], bounds[1]
        ends = bounds[2] if len(bounds) > 2 else "[]"
        value = getattr(obj, name)
        if isinstance(value, int) and not isinstance(value, bool) and ends == "[]":
            check_int(value, prefix + name, low=low, high=high)
        else:
            check_number(value, prefix + name, low=low, high=high, low_open=ends[0] == "(", high_open=ends[1] == ")")


def check_choice(value: Any, key: str, choices: Iterable[str]) -> str:
    """``value`` if it is one of ``choices``."""
    options = list(choices)
    if value not in options:
        raise ConfigError(f"{key}={_show(value)}: must be one of {', '.join(map(str, options))}"
                          f"{did_you_mean(str(value), options)}")
    return value


def check_device(value: Any, key: str = "device") -> str:
    """A torch device this machine has: ``cpu``, ``cuda`` or ``cuda:N``.

    torch is imported only for a CUDA value, so configs that stay on the CPU load fast.
    """
    text = str(value).strip()
    allowed = "cpu, cuda, cuda:N"
    if text == "cpu":
        return text
    kind, colon, index = text.partition(":")
    if kind != "cuda" or (colon and not index.isdigit()):
        raise ConfigError(f"{key}={_show(value)}: must be one of {allowed}{did_you_mean(kind, ('cpu', 'cuda'))}")
    import torch

    if not torch.cuda.is_available():
        why = "this torch build has no CUDA" if torch.version.cuda is None else "no CUDA device is visible"
        raise ConfigError(f"{key}={_show(value)}: CUDA is not available on this machine ({why}); allowed here: cpu")
    count = torch.cuda.device_count()
    if colon and int(index) >= count:
        raise ConfigError(f"{key}={_show(value)}: this machine has {count} CUDA device(s); allowed: cpu, cuda, "
                          f"cuda:0..cuda:{count - 1}")
    return text


def check_literal(key: str, value: Any) -> str:
    """A ``key=value`` value as given: omegaconf's ``${...}`` interpolations are refused (one line naming the
    key), so a value never silently becomes another key's value or an environment variable."""
    text = str(value)
    if "${" in text:
        raise ConfigError(f"{key}={_show(value)}: ${{...}} interpolations are not supported in key=value "
                          "arguments; write the value itself")
    return text


def check_input_file(path: Any, key: str) -> Path:
    """A file that exists and can be read (an input of a command, checked before any work)."""
    p = _as_path(path, key)
    if not p.exists():
        raise ConfigError(f"{key}={_show(path)}: the file does not exist")
    if p.is_dir():
        raise ConfigError(f"{key}={_show(path)}: is a directory; give a file")
    if not os.access(p, os.R_OK):
        raise ConfigError(f"{key}={_show(path)}: the file is not readable")
    return p


def check_input_dir(path: Any, key: str) -> Path:
    """A directory that exists and can be read (an input of a command, checked before any work)."""
    p = _as_path(path, key)
    if not p.is_dir():
        why = "is not a directory" if p.exists() else "the directory does not exist"
        raise ConfigError(f"{key}={_show(path)}: {why}")
    if not os.access(p, os.R_OK | os.X_OK):
        raise ConfigError(f"{key}={_show(path)}: the directory is not readable")
    return p


def check_field_values(obj: Any, prefix: str = "") -> Any:
    """What holds for every pasta setting, checked on every field of dataclass ``obj`` (and every item of a
    list field): a float is finite (NaN and infinity are no setting of any key) and an integer fits 64 bits
    (torch and numpy take nothing larger). A new key is covered without code of its own. Returns ``obj``."""
    from dataclasses import fields, is_dataclass

    if not is_dataclass(obj):
        return obj
    for f in fields(obj):
        value = getattr(obj, f.name)
        items = value if isinstance(value, (list, tuple)) else [value]
        for i, item in enumerate(items):
            where = f"{prefix}{f.name}" + (f"[{i}]" if items is value else "")
            if isinstance(item, float) and not math.isfinite(item):
                raise ConfigError(f"{where}={_show(item)}: must be a finite number")
            if isinstance(item, int) and not isinstance(item, bool) and not -(2**63) <= item < 2**63:
                raise ConfigError(f"{where}={_show(item)}: must be an integer that fits 64 bits")
    return obj


def check_output_file(path: Any, key: str, *, suffixes: Iterable[str] | None = None) -> Path:
    """A file path that can be written: not a directory, and its nearest existing parent is a writable
    directory (missing parents are created later by the writer). ``suffixes``: allowed extensions."""
    p = _as_path(path, key)
    if suffixes is not None:
        allowed = [s.lower() for s in suffixes]
        if p.suffix.lower() not in allowed:
            raise ConfigError(f"{key}={_show(path)}: the file name must end in {', '.join(allowed)}")
    if p.is_dir():
        raise ConfigError(f"{key}={_show(path)}: is a directory; give a file path")
    _check_writable_parent(p.parent, key, path)
    if p.exists() and not os.access(p, os.W_OK):
        raise ConfigError(f"{key}={_show(path)}: the file exists and is not writable")
    return p


def check_output_dir(path: Any, key: str) -> Path:
    """A directory path that exists and is writable, or can be created (its nearest existing ancestor is a
    writable directory). An existing *file* of that name is refused."""
    p = _as_path(path, key)
    if p.exists() and not p.is_dir():
        raise ConfigError(f"{key}={_show(path)}: exists and is not a directory; give a directory path")
    if p.is_dir():
        if not os.access(p, os.W_OK | os.X_OK):
            raise ConfigError(f"{key}={_show(path)}: the directory is not writable")
        return p
    _check_writable_parent(p.parent, key, path)
    return p


def _check_writable_parent(parent: Path, key: str, given: Any) -> None:
    probe = parent if str(parent) else Path(".")
    while not probe.exists():  # the nearest existing ancestor decides whether the rest can be created
        if probe.parent == probe:
            break
        probe = probe.parent
    if probe.exists() and not probe.is_dir():
        raise ConfigError(f"{key}={_show(given)}: {str(probe)!r} is a file, so the path cannot be created")
    if not os.access(probe, os.W_OK | os.X_OK):
        raise ConfigError(f"{key}={_show(given)}: directory {str(probe)!r} is not writable")


#: omegaconf's type messages in the words of pasta's own checks
_TYPE_WORDS = {"Integer": "must be an integer", "Float": "must be a number", "Boolean": "must be true or false"}


def plain_type_message(message: str) -> str:
    """``Value 'x' of type 'str' could not be converted to Integer`` -> ``must be an integer``."""
    for word, plain in _TYPE_WORDS.items():
        if message.endswith(f"could not be converted to {word}"):
            return plain
    if "is not a valid bool" in message:
        return "must be true or false"
    if message.startswith("Cannot convert '") and ("'DictConfig'" in message or "'ListConfig'" in message):
        return "must be a single value, not a list or a mapping"
    return message


def _as_path(path: Any, key: str) -> Path:
    text = str(path) if path is not None else ""
    if not text.strip():
        raise ConfigError(f"{key}=: needs a path")
    if "\0" in text:
        raise ConfigError(f"{key}={_show(path)}: a path cannot contain a NUL character")
    return Path(text).expanduser()


def _as_int(value: Any, key: str, allowed: str) -> int:
    if isinstance(value, bool):
        raise ConfigError(f"{key}={_show(value)}: must be {allowed}")
    if isinstance(value, int):
        return value
    if isinstance(value, float) and value.is_integer():
        return int(value)
    try:
        return int(str(value).strip())
    except ValueError:
        raise ConfigError(f"{key}={_show(value)}: must be {allowed}") from None


def _range_text(low: float | None, high: float | None, *, integer: bool = False, low_open: bool = False,
                high_open: bool = False) -> str:
    kind = "an integer" if integer else "a finite number"

    def text(bound: float) -> str:  # integers in full (1000000, not 1e+06)
        return str(bound) if isinstance(bound, int) else f"{bound:g}"

    if low is not None and high is not None:
        return f"{kind} in {'(' if low_open else '['}{text(low)}, {text(high)}{')' if high_open else ']'}"
    if low is not None:
        return f"{kind} {'>' if low_open else '>='} {text(low)}"
    if high is not None:
        return f"{kind} {'<' if high_open else '<='} {text(high)}"
    return kind


def _show(value: Any) -> str:
    text = str(value)
    return text if len(text) <= 60 else text[:57] + "..."


__all__ = ["MAX_THREADS", "SEED_MAX", "check_choice", "check_device", "check_field_values", "check_input_dir",
           "check_input_file", "check_int", "check_literal", "check_number", "check_output_dir", "check_output_file",
           "check_ranges", "check_seed", "check_threads", "plain_type_message"]
