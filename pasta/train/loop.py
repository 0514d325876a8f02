"""The one training loop shared by every learned module.

A module plugs in as a :class:`TrainTask`: its network, its batches, its loss and its validation. The
loop seeds every epoch from ``(seed, epoch)`` (so a resumed run repeats exactly what an uninterrupted
run would do), shows a rich progress bar on stderr, keeps the best weights by validation loss in
``OUT/model.*`` and the last state (weights, optimiser, history) in ``OUT/last.*``, and resumes from
``OUT/last.*`` when it exists. A module that shares its directory with another (a policy's reset pose
beside its ``model.*``) names its own checkpoint: ``fit(..., name="reset")`` writes ``OUT/reset.*`` and
``OUT/reset_last.*``.
"""

from __future__ import annotations

import math
import sys

import numpy as np
from contextlib import contextmanager
from collections.abc import Iterable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Protocol

import torch

from pasta.core.files import OutputLock
from pasta.io.checkpoint import IncompatibleCheckpointError, checkpoint_exists, load_checkpoint, save_checkpoint


#: bounds of the loop's counts: more is a typo, not a training run
MAX_EPOCHS = 100_000
MAX_BATCH = 1_000_000


@dataclass
class LoopConfig:
    """Settings of :func:`fit` (every one can be set as ``key=value`` on ``pasta train``).

    Attributes:
        epochs: passes over the training data.
        batch_size: examples per optimiser step.
        lr: Adam learning rate.
        weight_decay: Adam weight decay.
        seed: base seed; epoch ``e`` uses a generator seeded with ``(seed, e)``.
        resume: continue from ``OUT/last.*`` when present.
        progress: draw the progress bar (stderr).
        threads: torch CPU threads for the run (0 keeps torch's default); 1 is often fastest on a
            busy machine.
    """

    epochs: int = 30
    batch_size: int = 64
    lr: float = 1e-3
    weight_decay: float = 0.0
    seed: int = 0
    resume: bool = True
    progress: bool = True
    threads: int = 0

    def __post_init__(self) -> None:
        from pasta.config.validate import check_int, check_number, check_seed, check_threads

        check_int(self.epochs, "epochs", low=1, high=MAX_EPOCHS)
        check_int(self.batch_size, "batch_size", low=1, high=MAX_BATCH)
        check_number(self.lr, "lr", low=0.0, low_open=True, high=1.0)
        check_number(self.weight_decay, "weight_decay", low=0.0)
        check_seed(self.seed, "seed")
        check_threads(self.threads, "threads")


class TrainTask(Protocol):
    """What :func:`fit` needs from a module.

    Attributes:
        module: checkpoint module name (``"vae"``, ``"feasibility"``, ``"set_cost"``).
        model: the network; its ``state_dict`` is what is saved.
    """

    module: str

    @property
    def model(self) -> torch.nn.Module:
        """The network (read-only here: a task's own attribute may be a subclass)."""

    def config(self) -> dict[str, Any]:
        """JSON description saved beside the weights (sizes, normalisation, skill...)."""

    def batches(self, batch_size: int, generator: torch.Generator) -> Iterable[Any]:
        """One epoch of training batches, shuffled with ``generator``."""

    def loss(self, batch: Any, generator: torch.Generator) -> torch.Tensor:
        """Scalar training loss of ``batch`` (``generator`` for on-the-fly noise and negatives)."""

    def validate(self) -> dict[str, float]:
        """Held-out figures; must include ``"val_loss"`` (lower is better)."""


@dataclass
class FitResult:
    best_epoch: int
    best_val_loss: float
    epochs_run: int
    history: list[dict[str, float]] = field(default_factory=list)


def fit(task: TrainTask, cfg: LoopConfig, out_dir: str | Path, *, name: str = "model") -> FitResult:
    """Train ``task.model`` for ``cfg.epochs`` epochs; leave it holding the best validation weights.

    ``name``: the checkpoint of the best weights, ``OUT/<name>.*``; the state to resume from is
    ``OUT/last.*`` (``OUT/<name>_last.*`` for another name than ``model``, :func:`last_name`)."""
    with torch_threads(cfg.threads), OutputLock(out_dir, "out"):  # one trainer per folder
        return _fit(task, cfg, Path(out_dir), name)


def last_name(name: str = "model") -> str:
    """The resume checkpoint beside checkpoint ``name``: ``last`` for ``model``, else ``<name>_last``."""
    return "last" if name == "model" else f"{name}_last"


def numpy_rng(generator: torch.Generator) -> np.random.Generator:
    """A numpy generator drawn from ``generator`` (a task's batches in numpy, seeded by the loop's epoch)."""
    return np.random.default_rng(int(torch.randint(0, 2**62, (1,), generator=generator)))


@contextmanager
def torch_threads(n: int):
    """Run the block with ``n`` torch CPU threads (``0``: unchanged), restoring the previous count after."""
    before = torch.get_num_threads()
    if n > 0:
        torch.set_num_threads(n)
    try:
        yield
    finally:
        torch.set_num_threads(before)


def _fit(task: TrainTask, cfg: LoopConfig, out: Path, name: str) -> FitResult:
    optimiser = torch.optim.Adam(task.model.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
    start, best, history = _resume(task, optimiser, cfg, out, name) if cfg.resume else (0, (math.inf, -1), [])
    with _progress(cfg.progress) as bar:
        job = bar.add_task(task.module, total=cfg.epochs, completed=start)
        for epoch in range(start, cfg.epochs):
            gen = torch.Generator().manual_seed(cfg.seed * 1_000_003 + epoch)
            task.model.train()
            losses = []
            for batch in task.batches(cfg.batch_size, gen):
                loss = task.loss(batch, gen)
                optimiser.zero_grad(set_to_none=True)
                loss.backward()
                optimiser.step()
                losses.append(float(loss.detach()))
            task.model.eval()
            with torch.no_grad():
                figures = task.validate()
            record = {"epoch": epoch, "train_loss": sum(losses) / max(len(losses), 1), **figures}
            history.append(record)
            if figures["val_loss"] < best[0]:
                best = (figures["val_loss"], epoch)
                save_checkpoint(out, module=task.module, tensors=task.model.state_dict(), config=task.config(),
                                state={"epoch": epoch, "val_loss": figures["val_loss"], "loop": asdict(cfg)}, name=name)
            _save_last(task, optimiser, cfg, out, epoch, best, history, name)
            bar.update(job, advance=1, description=f"{task.module} val {figures['val_loss']:.4g} (best {best[0]:.4g} @{best[1]})")
    if best[1] >= 0:
        task.model.load_state_dict(load_checkpoint(out, module=task.module, name=name).tensors)
    return FitResult(best[1], best[0], cfg.epochs - start, history)


def _save_last(task: TrainTask, optimiser: torch.optim.Optimizer, cfg: LoopConfig, out: Path, epoch: int,
               best: tuple[float, int], history: list[dict[str, float]], name: str) -> None:
    tensors = {f"model.{k}": v for k, v in task.model.state_dict().items()}
    opt = optimiser.state_dict()
    for idx, slots in opt["state"].items():
        for key, value in slots.items():
            tensors[f"optim.{idx}.{key}"] = torch.as_tensor(value)
    state = {"epoch": epoch, "best_val_loss": best[0] if math.isfinite(best[0]) else None, "best_epoch": best[1],
             "history": history, "param_groups": opt["param_groups"], "loop": asdict(cfg)}
    save_checkpoint(out, module=task.module, tensors=tensors, config=task.config(), state=state, name=last_name(name))


def _resume(task: TrainTask, optimiser: torch.optim.Optimizer, cfg: LoopConfig, out: Path, name: str):
    if not checkpoint_exists(out, last_name(name)):
        return 0, (math.inf, -1), []
    ckpt = load_checkpoint(out, module=task.module, name=last_name(name))
    if ckpt.config != task.config():
        diff = sorted(k for k in set(ckpt.config) | set(task.config()) if ckpt.config.get(k) != task.config().get(k))
        raise IncompatibleCheckpointError(
            f"cannot resume from {ckpt.path}: its config differs in {', '.join(diff)}; "
            "use a new out= directory or resume=false"
        )
    task.model.load_state_dict({k[6:]: v for k, v in ckpt.tensors.items() if k.startswith("model.")})
    slots: dict[int, dict[str, torch.Tensor]] = {}
    for key, value in ckpt.tensors.items():
        if key.startswith("optim."):
            _, idx, name = key.split(".", 2)
            slots.setdefault(int(idx), {})[name] = value
    optimiser.load_state_dict({"state": slots, "param_groups": ckpt.state["param_groups"]})
    for group in optimiser.param_groups:
        group["lr"] = cfg.lr
    best_val = ckpt.state["best_val_loss"]
    best = (math.inf if best_val is None else best_val, ckpt.state["best_epoch"])
    return ckpt.state["epoch"] + 1, best, list(ckpt.state["history"])


def _progress(enabled: bool):
    """The epochs bar, with an ETA, on stderr when it is a terminal (:func:`pasta.core.progress.on_terminal`)."""
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

    from pasta.core.progress import on_terminal

    return Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                    TimeRemainingColumn(), console=Console(file=sys.stderr), disable=not on_terminal(enabled),
                    transient=False)
