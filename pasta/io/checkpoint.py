"""Checkpoints: weights in safetensors, a JSON header beside them. No pickle anywhere.

A checkpoint named ``NAME`` in directory ``DIR`` is two files:

- ``DIR/NAME.safetensors``: the tensors (``str -> torch.Tensor``);
- ``DIR/NAME.json``: ``{"format_version", "module", "config", "state"}``; ``config`` holds what is
  needed to rebuild the module (sizes, normalisation, the skill it belongs to), ``state`` free JSON
  (epoch, best validation loss, ...).

Format version 2 writes every config key its loader needs: the loaders read no defaults for keys a file
lacks. A file of another version (1: written before that rule) fails with one error naming its version
and what to do; pasta's shipped weights are version 2.

:func:`load_checkpoint` checks the format version, the module name and any expected config values and
raises :class:`IncompatibleCheckpointError` listing every mismatch.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pasta.core.errors import ConfigError, MissingComponentError
from pasta.core.files import write_bytes, write_text

if TYPE_CHECKING:
    import torch

#: version 2: every config key a loader needs is written (version 1 files relied on the loaders' defaults)
FORMAT_VERSION = 2

__all__ = [
    "FORMAT_VERSION",
    "Checkpoint",
    "IncompatibleCheckpointError",
    "checkpoint_exists",
    "load_checkpoint",
    "save_checkpoint",
]


class IncompatibleCheckpointError(ConfigError):
    """A checkpoint exists but does not fit what the caller expects (module, sizes, format)."""


class Checkpoint:
    """A loaded checkpoint: ``tensors`` (name -> tensor), ``config`` and ``state`` (JSON dicts)."""

    def __init__(self, path: Path, module: str, tensors: dict[str, torch.Tensor], config: dict, state: dict) -> None:
        self.path, self.module, self.tensors, self.config, self.state = path, module, tensors, config, state

    def __repr__(self) -> str:
        return f"Checkpoint({self.path}, module={self.module!r}, {len(self.tensors)} tensors)"


def _paths(directory: str | os.PathLike, name: str) -> tuple[Path, Path]:
    d = Path(directory)
    return d / f"{name}.safetensors", d / f"{name}.json"


def checkpoint_exists(directory: str | os.PathLike, name: str = "model") -> bool:
    """Whether ``directory`` holds both files of checkpoint ``name``."""
    weights, header = _paths(directory, name)
    return weights.is_file() and header.is_file()


def save_checkpoint(
    directory: str | os.PathLike,
    *,
    module: str,
    tensors: Mapping[str, torch.Tensor],
    config: Mapping[str, Any],
    state: Mapping[str, Any] | None = None,
    name: str = "model",
) -> Path:
    """Write checkpoint ``name`` into ``directory`` (created if needed) atomically; return the weights path.

    Args:
        module: what the weights are (``"vae"``, ``"feasibility"``, ``"set_cost"``); checked on load.
        tensors: ``str -> torch.Tensor``; saved contiguous, on the CPU.
        config: JSON-serialisable description needed to rebuild the module.
        state: JSON-serialisable training state.
    """
    from safetensors.torch import save

    weights, header = _paths(directory, name)
    flat = {k: v.detach().to("cpu").contiguous() for k, v in tensors.items()}
    doc = {"format_version": FORMAT_VERSION, "module": module, "config": dict(config), "state": dict(state or {})}
    text = json.dumps(doc, indent=2, sort_keys=True)
    # each file is written whole (an interrupted save never leaves a half-written one) and never through a link
    write_bytes(weights, save(flat, metadata={"module": module, "format_version": str(FORMAT_VERSION)}))
    write_text(header, text + "\n")
    return weights


def load_checkpoint(
    directory: str | os.PathLike,
    *,
    module: str,
    expect: Mapping[str, Any] | None = None,
    name: str = "model",
    hint: str = "",
) -> Checkpoint:
    """Load checkpoint ``name`` from ``directory`` and check it is a ``module`` with the ``expect`` config.

    Args:
        module: expected module name.
        expect: config keys that must have these values (e.g. ``{"z_dim": 2, "skill": "cut"}``).
        hint: how to produce the checkpoint (a training command), added to the missing-file and
            format-version errors.

    Raises:
        MissingComponentError: a file is missing.
        IncompatibleCheckpointError: wrong format version, module or config values (all listed).
    """
    from safetensors.torch import load_file

    weights, header = _paths(directory, name)
    missing = [str(p) for p in (weights, header) if not p.is_file()]
    if missing:
        fix = f"; {hint}" if hint else ""
        raise MissingComponentError(f"no {module} checkpoint at {directory}: missing {', '.join(missing)}{fix}")
    try:
        doc = json.loads(header.read_text())
    except json.JSONDecodeError as exc:
        raise IncompatibleCheckpointError(f"{header} is not valid JSON: {exc}") from None
    version = doc.get("format_version")
    if version != FORMAT_VERSION:
        fix = hint or "retrain it with this pasta (to resume a run, start over with resume=false)"
        raise IncompatibleCheckpointError(
            f"checkpoint {weights} has format_version {version!r}; this pasta reads version {FORMAT_VERSION} (every "
            f"setting its loader needs written out): {fix}")
    problems = []
    if doc.get("module") != module:
        problems.append(f"module is {doc.get('module')!r}, expected {module!r}")
    config = doc.get("config", {})
    for key, value in (expect or {}).items():
        if key not in config:
            problems.append(f"config has no '{key}' (expected {value!r})")
        elif config[key] != value:
            problems.append(f"{key} is {config[key]!r}, expected {value!r}")
    if problems:
        raise IncompatibleCheckpointError(f"checkpoint {weights} does not fit: " + "; ".join(problems))
    return Checkpoint(weights, module, load_file(str(weights)), config, doc.get("state", {}))


def weights_digest(directory: str | os.PathLike, name: str = "model") -> str:
    """The first 16 hex digits of the SHA-256 of ``directory/<name>.safetensors`` (``""`` when there is none): which
    weights a result was made with."""
    import hashlib

    path = Path(directory) / f"{name}.safetensors"
    if not path.is_file():
        return ""
    return hashlib.sha256(path.read_bytes()).hexdigest()[:16]
