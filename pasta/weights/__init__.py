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

__all__ = ["ROOT", "bundle", "models_root", "module_dir", "shipped", "train_into", "weight_overrides"]

#: the directory of the shipped weights
ROOT = Path(__file__).resolve().parent
_FILES = ("model.safetensors", "model.json", "metrics.json", "reset.safetensors", "reset.json")


def models_root(models: str | Path | None = None) -> Path:
    """The weights root to load from: ``models`` when given (a ``pasta train`` output), else the shipped one.

    Raises:
        ConfigError: ``models`` names no directory (a typo would otherwise load the shipped weights through
            :func:`module_dir` without a word).
    """
    if models in (None, ""):
        return ROOT
    root = Path(models)
    if not root.is_dir():
        from pasta.core.errors import ConfigError

        why = "is not a directory" if root.exists() else "the directory does not exist"
        raise ConfigError(f"models={models}: {why} (a `pasta train ... out=DIR` root; leave models= out for the "
                          "shipped weights)")
    return root


def weight_overrides(root: str | Path, given: list[str]) -> list[str]:
    """``encoder.weights=ROOT/vae`` and ``cost_model.weights=ROOT/cost`` (:func:`module_dir`: the shipped ones when
    the root has none), except for keys already in ``given`` (``key=value`` items): the run config's weights
    under one models root."""
    keys = {item.partition("=")[0].strip() for item in given}
    return [f"{key}={module_dir(root, sub)}" for key, sub in (("encoder.weights", "vae"), ("cost_model.weights", "cost"))
            if key not in keys]


def module_dir(root: str | Path, sub: str) -> Path:
    """Where the module ``sub`` (``vae``, ``cost``, ``feasibility/<skill>``, ``policy/<skill>``) of models root ``root``
    is: ``root/sub`` when it holds a trained module, else the shipped ``sub`` when that does, so a root that trains
    only a new skill (its feasibility, its policy) plans with the shipped VAE, cost and skills, copying nothing.
    Networks that read latents belong to the VAE they were trained on: a root with a VAE of its own never borrows
    the shipped cost or skills. Otherwise ``root/sub`` (so a missing module is named where the user put it)."""
    own = Path(root) / sub
    if _trained(own) or not _trained(ROOT / sub):
        return own
    if sub != "vae" and _trained(Path(root) / "vae"):
        return own
    return ROOT / sub


def _trained(directory: Path) -> bool:
    return (directory / "model.safetensors").is_file()


def train_into(root: str | Path) -> tuple[str, str]:
    """``(out=, extra)`` for a message that tells how to train a module missing under models root ``root``: the
    root itself, but never the shipped weights inside the installed package (then ``models`` and the
    ``models=models`` a run needs to use it)."""
    if Path(root).resolve() == ROOT.resolve():
        return "models", " (then run with models=models)"
    return str(root), ""


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
