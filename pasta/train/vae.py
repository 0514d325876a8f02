"""Training of the point-cloud VAE (entities, or whole scenes for the Flat 3D baseline).

Loss per example, in units of the global ``scale``: Chamfer distance between decoded and observed
points, plus an exact-assignment EMD term on a small subset (the mean distance of an optimal
one-to-one matching, scipy's Hungarian solver), plus ``kl_weight`` times the KL to ``N(0, I)``.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from pasta.core.errors import InputError
from pasta.core.files import save_with
from pasta.nn.vae import MODULE, PointVAE, cube_template
from pasta.demos.data import Demo, demo_entities


#: the most points per entity (or scene) a trainer samples
MAX_POINTS = 100_000


@dataclass
class VAETrainConfig:
    """VAE settings (``key=value`` on ``pasta train vae``).

    Attributes:
        z_dim: ``Z``, the shape code size (the paper uses 2).
        width: PointNet width.
        fold_hidden: folding decoder width.
        input_points: points per example fed to the encoder (random subset when training).
        target_points: decoded points compared by Chamfer per example.
        emd_points: points of the exact-assignment EMD term.
        emd_weight: weight of that term.
        kl_weight: weight of the KL term.
        num_points: points per entity after decomposition.
        stride: use every ``stride``-th demonstration step.
        flat: train on whole scenes (Flat 3D baseline) instead of entities.
        val_fraction: share of demonstrations held out (per skill).
        max_val: validation examples evaluated each epoch (the final figures use all).
    """

    z_dim: int = 2
    width: int = 128
    fold_hidden: int = 96
    input_points: int = 256
    target_points: int = 256
    emd_points: int = 128
    emd_weight: float = 1.0
    kl_weight: float = 1e-3
    num_points: int = 1000
    stride: int = 1
    flat: bool = False
    val_fraction: float = 0.2
    max_val: int = 256

    def __post_init__(self) -> None:
        from pasta.config.validate import check_ranges

        check_ranges(self, {"z_dim": (1, 1024), "width": (1, 1 << 16), "fold_hidden": (1, 1 << 16),
                            "input_points": (1, MAX_POINTS), "target_points": (1, MAX_POINTS),
                            "emd_points": (1, MAX_POINTS), "emd_weight": (0.0, None), "kl_weight": (0.0, None),
                            "num_points": (1, MAX_POINTS), "stride": (1, None), "val_fraction": (0.0, 1.0, "[)"),
                            "max_val": (1, None)})


def collect_clouds(demos: list[Demo], cfg: VAETrainConfig, *, seed: int = 0) -> np.ndarray:
    """``(N, num_points, 3)`` training clouds: every entity of every step, or whole scenes if ``cfg.flat``
    (every ``stride``-th step and, when the demonstration stores it, its ``final_dough``)."""
    from pasta.core.decompose import resample

    clouds = []
    for demo in demos:
        if cfg.flat:
            rng = np.random.default_rng([seed, demo.index])
            steps = range(0, len(demo.dough), max(1, cfg.stride))
            clouds += [resample(demo.dough[t], cfg.num_points, rng) for t in steps]
            if demo.final_dough is not None:  # the settled scene after the skill (what a goal looks like)
                clouds.append(resample(demo.final_dough, cfg.num_points, rng))
        else:
            ents = demo_entities(demo, num_points=cfg.num_points, stride=cfg.stride, seed=seed)
            clouds += [c for step in ents.clouds for c in step]
    if not clouds:
        raise InputError("no point clouds to train the VAE on")
    return np.stack(clouds).astype(np.float32)


class VAETask:
    """:class:`pasta.train.loop.TrainTask` of the VAE."""

    module = MODULE

    def __init__(self, train: np.ndarray, val: np.ndarray, cfg: VAETrainConfig, *, seed: int = 0) -> None:
        self.cfg = cfg
        torch.manual_seed(seed)
        self.model = PointVAE(cfg.z_dim, cfg.width, cfg.fold_hidden)
        train_t = torch.from_numpy(train)
        centroids = train_t.mean(1)
        self.train = train_t - centroids[:, None]
        self.model.scale.fill_(float(self.train.pow(2).sum(-1).mean().sqrt()))
        self.model.t_low.copy_(centroids.amin(0))
        self.model.t_high.copy_(centroids.amax(0))
        self.val = torch.from_numpy(val)
        pick = torch.randperm(len(self.val), generator=torch.Generator().manual_seed(seed))[: cfg.max_val]
        self.val_epoch = self.val[pick.sort().values]

    def config(self) -> dict[str, Any]:
        return {**self.model.config(), "scope": "scene" if self.cfg.flat else "entity",
                "num_points": self.cfg.num_points, "train": _train_dict(self.cfg)}

    def batches(self, batch_size: int, generator: torch.Generator):
        order = torch.randperm(len(self.train), generator=generator)
        for i in range(0, len(order), batch_size):
            yield order[i : i + batch_size]


    def loss(self, batch: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
        cfg, model = self.cfg, self.model
        clouds = self.train[batch]  # (B, P, 3) centred
        b, p = clouds.shape[:2]
        idx = torch.rand(b, p, generator=generator).argsort(-1)
        inputs = clouds.gather(1, idx[:, : cfg.input_points, None].expand(-1, -1, 3))
        target = clouds.gather(1, idx[:, -cfg.target_points :, None].expand(-1, -1, 3)) / model.scale
        mean, logvar = model.encode_stats(inputs)
        z = mean + (0.5 * logvar).exp() * torch.randn(mean.shape, generator=generator)
        pred = model.decode_normalised(z, cube_template(cfg.target_points, generator=generator))
        kl = 0.5 * (mean.pow(2) + logvar.exp() - 1 - logvar).sum(-1).mean()
        return chamfer_loss(pred, target) + cfg.emd_weight * assignment_emd(
            pred[:, : cfg.emd_points], target[:, : cfg.emd_points]
        ) + cfg.kl_weight * kl

    @torch.no_grad()
    def validate(self) -> dict[str, float]:
        err = reconstruction_errors(self.encoder(), self.val_epoch)
        return {"val_loss": float(err.mean()), "val_chamfer": float(err.mean())}

    def encoder(self):
        from pasta.nn.config import FlatEncoderConfig, PointVAEEncoderConfig
        from pasta.nn.encoders import FlatEncoder, PointVAEEncoder

        if self.cfg.flat:
            return FlatEncoder(FlatEncoderConfig(weights="", encode_points=self.cfg.input_points), model=self.model)
        return PointVAEEncoder(PointVAEEncoderConfig(weights="", encode_points=self.cfg.input_points), model=self.model)


def _train_dict(cfg: VAETrainConfig) -> dict[str, Any]:
    """The settings saved with the weights."""
    return asdict(cfg)


def chamfer_loss(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Mean over the batch of the squared-distance Chamfer of ``a (B, P, 3)`` and ``b (B, Q, 3)``."""
    d = torch.cdist(a, b).pow(2)
    return (d.min(-1).values.mean(-1) + d.min(-2).values.mean(-1)).mean()


def assignment_emd(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Mean matched distance under the optimal one-to-one assignment of ``a (B, Q, 3)`` to ``b (B, Q, 3)``."""
    from scipy.optimize import linear_sum_assignment

    d = torch.cdist(a, b)
    host = d.detach().cpu().numpy()
    cols = torch.from_numpy(np.stack([linear_sum_assignment(m)[1] for m in host])).to(d.device)
    return d.gather(2, cols[:, :, None]).mean()


def reconstruction_errors(encoder: Any, clouds: torch.Tensor, *, batch: int = 64) -> torch.Tensor:
    """Chamfer (world units, :func:`pasta.core.metrics.chamfer`) of each cloud ``(N, P, 3)`` and its reconstruction."""
    from pasta.core.metrics import chamfer

    out = []
    for i in range(0, len(clouds), batch):
        chunk = clouds[i : i + batch]
        recon = encoder.decode(encoder.encode(chunk), chunk.shape[1])
        out.append(chamfer(recon, chunk))
    return torch.cat(out)


def reconstruction_figure(encoder: Any, clouds: torch.Tensor, path: str | Path, *, title: str = "") -> Path:
    """Save a PNG of ``clouds (5, P, 3)`` (top row) and their reconstructions (bottom row)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    recon = encoder.decode(encoder.encode(clouds), clouds.shape[1]).numpy()
    err = reconstruction_errors(encoder, clouds).numpy()
    n = len(clouds)
    fig = plt.figure(figsize=(3.2 * n, 6.4))
    for j in range(n):
        real = clouds[j].numpy()
        lo, hi = real.min(0), real.max(0)
        centre, half = (lo + hi) / 2, max((hi - lo).max() / 2, 1e-3) * 1.15
        for row, (pts, label) in enumerate(((real, "held-out"), (recon[j], f"reconstruction\nChamfer {err[j]:.2e}"))):
            ax = fig.add_subplot(2, n, row * n + j + 1, projection="3d")
            # y is up in pasta; matplotlib's vertical axis is its third.
            ax.scatter(pts[:, 0], pts[:, 2], pts[:, 1], s=1.5, c=pts[:, 1], cmap="viridis")
            ax.set_xlim(centre[0] - half, centre[0] + half)
            ax.set_ylim(centre[2] - half, centre[2] + half)
            ax.set_zlim(centre[1] - half, centre[1] + half)
            ax.set_title(label, fontsize=9)
            ax.set_xticks([]), ax.set_yticks([]), ax.set_zticks([])
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    path = save_with(path, lambda fh: fig.savefig(fh, dpi=90, format="png"))
    plt.close(fig)
    return path


def vae_metrics(task: VAETask, out_dir: Path) -> dict[str, Any]:
    """Held-out figures of the trained VAE, and the reconstruction PNG ``out_dir/reconstructions.png``."""
    from pasta.core.metrics import chamfer

    encoder = task.encoder()
    val = task.val
    err = reconstruction_errors(encoder, val).numpy()
    # Sampling floor: Chamfer between two disjoint halves of the same observed cloud.
    half = val.shape[1] // 2
    floor = chamfer(val[:, :half], val[:, half : 2 * half]).numpy()
    pick = np.linspace(0, len(val) - 1, min(5, len(val))).round().astype(int)
    png = reconstruction_figure(encoder, val[pick], out_dir / "reconstructions.png",
                                title="held-out pieces (top) and VAE reconstructions (bottom)")
    return {
        "heldout_examples": int(len(val)),
        "heldout_chamfer_mean": float(err.mean()),
        "heldout_chamfer_median": float(np.median(err)),
        "heldout_chamfer_p90": float(np.quantile(err, 0.9)),
        "resampling_floor_chamfer_mean": float(floor.mean()),
        "figure": png.name,
    }
