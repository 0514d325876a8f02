"""Distances between point clouds and the task score.

- :func:`chamfer`: symmetric squared-nearest-neighbour Chamfer distance (means of both directions,
  summed), used for entity matching, the "unchanged entity" filter and cost-model labels.
- :func:`emd`: exact earth mover's distance (W1, Euclidean ground cost, uniform weights) on ``n``
  sampled points of each cloud, the evaluation metric.
- :func:`normalized_improvement`: ``(EMD_0 - EMD_T) / EMD_0``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from pasta.core.errors import InputError
from pasta.core.shapes import check_points


def chamfer(a: Any, b: Any) -> Any:
    """Chamfer distance of ``a (..., P, 3)`` and ``b (..., Q, 3)`` -> ``(...)``; torch in, torch out (else numpy)."""
    import torch

    is_torch = isinstance(a, torch.Tensor)
    ta, tb = torch.as_tensor(a, dtype=torch.float32), torch.as_tensor(b, dtype=torch.float32)
    d = torch.cdist(ta, tb).pow(2)
    out = d.min(-1).values.mean(-1) + d.min(-2).values.mean(-1)
    return out if is_torch else out.numpy()


def sample_points(points: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` points of ``points (P, 3)``: without replacement when ``P >= n``, else with replacement."""
    idx = rng.choice(len(points), size=n, replace=len(points) < n)
    return points[idx]


def emd(a: np.ndarray, b: np.ndarray, *, n: int = 500, seed: int = 0) -> float:
    """Exact EMD between ``a (P, 3)`` and ``b (Q, 3)`` on ``n`` points sampled from each with ``seed``.

    Clouds of equal size are subsampled at the same indices (the same simulator particles).
    """
    import ot

    check_points(a, "first cloud")
    check_points(b, "second cloud")
    rng = np.random.default_rng(seed)
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    if len(a) == len(b):  # same particles observed twice: keep the correspondence of the subsample
        idx = rng.choice(len(a), size=n, replace=len(a) < n)
        pa, pb = a[idx], b[idx]
    else:
        pa, pb = sample_points(a, n, rng), sample_points(b, n, rng)
    w = np.full(n, 1.0 / n)
    return float(ot.emd2(w, w, ot.dist(pa, pb, metric="euclidean")))


def normalized_improvement(emd_initial: float, emd_final: float) -> float:
    """``(EMD_0 - EMD_T) / EMD_0``: 0 for no progress, 1 for reaching the goal exactly."""
    if not emd_initial > 0:
        raise InputError(f"initial EMD must be > 0 to normalise, got {emd_initial}")
    return (emd_initial - emd_final) / emd_initial
