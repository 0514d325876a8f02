"""The trained weights that ship with pasta, and where pasta looks for weights.

Layout (the same as a ``pasta train ... out=MODELS`` root)::

    pasta/weights/vae/             entity VAE (encoder ``pc_vae``)
    pasta/weights/feasibility/<skill>/
    pasta/weights/cost/            pair cost (``set_cost``)
    pasta/weights/policy/<skill>/  behaviour-cloned policies
    pasta/weights/flat/{vae,feasibility/<skill>,cost}/   the Flat 3D baseline

Each directory holds ``model.safetensors`` + ``model.json`` (the loader's format, no pickle) and the
``metrics.json`` that its trainer wrote (held-out quality figures and the training settings); a policy
directory may also hold a learned reset pose, ``reset.safetensors`` + ``reset.json`` (``pasta.policy.reset``, trained by ``pasta.train.reset``).
:func:`bundle` copies a trained root here; ``pasta weights`` lists what is shipped.
"""

from __future__ import annotations

from pathlib import Path

from pasta.core.files import write_bytes

__all__ = ["ROOT", "bundle", "models_root", "shipped", "weight_overrides"]

#: the directory of the shipped weights
ROOT = Path(__file__).resolve().parent
_FILES = ("model.safetensors", "model.json", "metrics.json", "reset.safetensors", "reset.json")


def models_root(models: str | Path | None = None) -> Path:
    """The weights root to load from: ``models`` when given (a ``pasta train`` output), else the shipped one."""
    return Path(models) if models not in (None, "") else ROOT


def weight_overrides(root: str | Path, given: list[str]) -> list[str]:
    """``encoder.weights=ROOT/vae`` and ``cost_model.weights=ROOT/cost``, except for keys already in ``given``
    (``key=value`` items): the run config's weights under one models root."""
    keys = {item.partition("=")[0].strip() for item in given}
    return [f"{key}={Path(root) / sub}" for key, sub in (("encoder.weights", "vae"), ("cost_model.weights", "cost"))
            if key not in keys]


def shipped(root: str | Path | None = None) -> list[str]:
    """Module directories (relative to ``root``, default the shipped root) that hold a ``model.safetensors``."""
    base = models_root(root)
    return sorted(str(p.parent.relative_to(base)) for p in base.rglob("model.safetensors"))


def bundle(source: str | Path, target: str | Path | None = None) -> list[str]:
    """Copy the final weights (not the resume checkpoints) of every module under ``source`` into ``target``.

    Returns the module directories copied (those whose trainer finished, i.e. wrote ``metrics.json``). Only ``model.*``, ``metrics.json`` and a policy's
    ``reset.*`` are copied; ``last.*`` (optimiser state for resuming) stays behind.
    """
    source, target = Path(source), Path(target) if target is not None else ROOT
    copied = []
    for rel in shipped(source):
        if not (source / rel / "metrics.json").exists():  # unfinished: the trainer writes it last
            continue
        for name in _FILES:
            if (source / rel / name).exists():  # written whole, never through a link (pasta.core.files)
                write_bytes(target / rel / name, (source / rel / name).read_bytes())
        copied.append(rel)
    return copied
