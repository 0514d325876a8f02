"""``pasta train`` as a function: read a dataset, split it by demonstration, fit one module, report.

:func:`train` is what the command calls; tests call it directly. Each module writes into its own
directory under the models root ``out`` (see :mod:`pasta.nn`) and leaves ``metrics.json`` there.

Flat 3D baseline (``flat=true``, layout in :mod:`pasta.nn.flat`): a models root of its own, e.g.
``out=models/flat``, with the same sub-directories (``vae``, ``feasibility/<skill>``, ``cost``); its
feasibility and cost read the scene VAE ``OUT/vae``.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from pasta.config.overrides import build_many
from pasta.core.errors import ConfigError, did_you_mean
from pasta.core.files import write_json
from pasta.nn import COST_DIR, FEASIBILITY_DIR, VAE_DIR
from pasta.train.cost import CostTask, CostTrainConfig, entity_pairs
from pasta.demos.data import load_demos, split_by_demo
from pasta.train.feasibility import FeasibilityTask, FeasibilityTrainConfig, positive_tuples
from pasta.train.latents import encode_demos, encode_scenes
from pasta.train.loop import LoopConfig, fit, torch_threads
from pasta.train.vae import VAETask, VAETrainConfig, collect_clouds, vae_metrics

MODULES = ("vae", "feasibility", "cost")
_MODULE_CONFIG = {"vae": VAETrainConfig, "feasibility": FeasibilityTrainConfig, "cost": CostTrainConfig}
#: loop defaults that differ per module
_LOOP_DEFAULTS: dict[str, dict[str, Any]] = {
    "vae": {"epochs": 40, "batch_size": 32, "lr": 1e-3},
    "feasibility": {"epochs": 30, "batch_size": 64, "lr": 1e-3},
    "cost": {"epochs": 60, "batch_size": 256, "lr": 1e-3},
}


def parse_overrides(module: str, overrides: Mapping[str, str]) -> tuple[LoopConfig, Any]:
    """Split ``key=value`` strings into the loop config and the module's config, typed and validated."""
    if module not in MODULES:
        raise ConfigError(f"unknown module '{module}'{did_you_mean(module, MODULES)}; choose one of {', '.join(MODULES)}")
    values = {**_LOOP_DEFAULTS[module], **overrides}
    loop, cfg = build_many(values, [LoopConfig, _MODULE_CONFIG[module]], command=f"pasta train {module}")
    return loop, cfg


def train(module: str, data: str | Path, out: str | Path, overrides: Mapping[str, str] | None = None) -> dict[str, Any]:
    """Train ``module`` (``vae``, ``feasibility`` or ``cost``) on dataset ``data`` into models root ``out``.

    Returns:
        the held-out figures, also written to ``metrics.json`` beside the weights.
    """
    loop, cfg = parse_overrides(module, overrides or {})
    with torch_threads(loop.threads):  # data preparation too, not only the loop
        trainers: dict[str, Callable[[Path, Path, LoopConfig, Any], dict[str, Any]]] = {
            "vae": _train_vae, "feasibility": _train_feasibility, "cost": _train_cost}
        return trainers[module](Path(data), Path(out), loop, cfg)


def _split(data: Path, cfg: Any, loop: LoopConfig, stage: str, skills: list[str] | None = None):
    demos = load_demos(data, skills, stage=stage)
    train, val = split_by_demo(demos, val_fraction=cfg.val_fraction, seed=loop.seed)
    if not val:
        print("pasta train: warning: too few demonstrations to hold one out; validating on the training set", file=sys.stderr)
        val = train
    return train, val


def _finish(directory: Path, module: str, result: Any, figures: dict[str, Any], data: Path, n_train: int, n_val: int) -> dict[str, Any]:
    metrics = {"module": module, "data": str(data), "train_demos": n_train, "heldout_demos": n_val,
               "best_epoch": result.best_epoch, "best_val_loss": result.best_val_loss, **figures}
    write_json(directory / "metrics.json", metrics)
    return metrics


def _train_vae(data: Path, out: Path, loop: LoopConfig, cfg: VAETrainConfig) -> dict[str, Any]:
    directory = out / VAE_DIR
    train, val = _split(data, cfg, loop, "vae")
    task = VAETask(collect_clouds(train, cfg, seed=loop.seed), collect_clouds(val, cfg, seed=loop.seed), cfg, seed=loop.seed)
    result = fit(task, loop, directory)
    return _finish(directory, "vae", result, vae_metrics(task, directory), data, len(train), len(val))


def _load_encoder(out: Path, path: str, flat: bool = False):
    """The ``pc_vae`` encoder of ``path`` (default ``OUT/vae``), or with ``flat`` the ``flat`` one."""
    if flat:
        from pasta.nn.flat import load_flat_encoder

        return load_flat_encoder(out, vae=path)
    from pasta.nn.config import PointVAEEncoderConfig
    from pasta.nn.encoders import PointVAEEncoder

    if not path:  # the models root's own VAE, else the shipped one (a new skill trains on the shipped latents)
        from pasta.weights import module_dir

        path = str(module_dir(out, VAE_DIR))
        if Path(path) != out / VAE_DIR:
            print(f"note: {out} has no trained VAE; encoding with the shipped one ({path})", file=sys.stderr)
    return PointVAEEncoder(PointVAEEncoderConfig(weights=path))


def _encode(demos: list, encoder: Any, cfg: Any, seed: int, *, pairs_only: bool = False) -> list:
    """Entity sets of ``demos`` (:func:`encode_demos`), or whole scenes with ``cfg.flat`` (:func:`encode_scenes`);
    ``pairs_only``: flat scenes are only (first step, after the skill)."""
    if cfg.flat:
        stride = None if pairs_only else cfg.stride
        return encode_scenes(demos, encoder, num_points=cfg.num_points, stride=stride, seed=seed)
    return encode_demos(demos, encoder, num_points=cfg.num_points, stride=cfg.stride, seed=seed)


def _train_feasibility(data: Path, out: Path, loop: LoopConfig, cfg: FeasibilityTrainConfig) -> dict[str, Any]:
    from pasta.plugins import get_plugins

    if not cfg.skill:
        raise ConfigError("`pasta train feasibility` needs skill=NAME (a registered skill)")
    spec = get_plugins().skills.info(cfg.skill).spec
    n_in, n_out = (1, 1) if cfg.flat else (spec.n_in, spec.n_out)  # Flat 3D: scene -> scene
    encoder = _load_encoder(out, cfg.vae, cfg.flat)
    train, val = _split(data, cfg, loop, "feasibility", [cfg.skill])
    enc = {name: _encode(d, encoder, cfg, loop.seed, pairs_only=True) for name, d in (("train", train), ("val", val))}
    tuples = {name: positive_tuples(e, n_in, n_out, cfg, seed=loop.seed) for name, e in enc.items()}
    task = FeasibilityTask(cfg.skill, n_in, n_out, tuples["train"], tuples["val"], encoder, cfg, seed=loop.seed)
    directory = out / FEASIBILITY_DIR / cfg.skill
    result = fit(task, loop, directory)
    figures: dict[str, Any] = {f"heldout_{k[4:]}": v for k, v in task.validate().items() if k != "val_loss"}
    figures.update(skill=cfg.skill, train_positives=len(task.train_in), heldout_positives=len(task.val_in),
                   heldout_hard_negatives=len(task.val_hard[0]))
    return _finish(directory, "feasibility", result, figures, data, len(train), len(val))


def _train_cost(data: Path, out: Path, loop: LoopConfig, cfg: CostTrainConfig) -> dict[str, Any]:
    encoder = _load_encoder(out, cfg.vae, cfg.flat)
    train, val = _split(data, cfg, loop, "cost")
    pairs = {name: entity_pairs(_encode(d, encoder, cfg, loop.seed), cfg, seed=loop.seed + i)
             for i, (name, d) in enumerate((("train", train), ("val", val)))}
    task = CostTask(pairs["train"], pairs["val"], encoder.latent_dim, cfg, seed=loop.seed)
    directory = out / COST_DIR
    result = fit(task, loop, directory)
    figures = {f"heldout_{k[4:]}": v for k, v in task.validate().items() if k != "val_loss"}
    figures.update(train_pairs=len(task.train_a), heldout_pairs=len(task.val_a))
    return _finish(directory, "cost", result, figures, data, len(train), len(val))
