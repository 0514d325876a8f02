"""Scene decomposition: split a dough point cloud into entities (pieces) with DBSCAN.

Clusters with fewer than ``min_points`` points count as noise, and every noise point joins the cluster
of its nearest kept point, so no point is lost. Entities are numbered in a fixed order (centroid ``x``,
then ``z``, then ``y``) and each is resampled to ``num_points`` points with a seeded generator.

The same function serves training data (``min_points=10`` in the paper) and planning/execution (the
paper's release silently used 50 there; callers pass what they mean).

DBSCAN's memory grows with the number of neighbour pairs, i.e. with the square of the point count for a
dense cloud (1e5 points took 6 GB). Callers that accept clouds of any size bound them first with
:func:`voxel_downsample`.
"""

from __future__ import annotations

import numpy as np

from pasta.core.errors import InputError

__all__ = ["decompose", "decompose_labels", "resample", "voxel_downsample"]


def decompose_labels(
    points: np.ndarray, *, eps: float = 0.03, min_samples: int = 6, min_points: int = 10
) -> np.ndarray:
    """Label every point of ``points (P, 3)`` with its entity index.

    Args:
        points: ``(P, 3)`` dough cloud (``np.ndarray``).
        eps: DBSCAN neighbourhood radius (metres).
        min_samples: DBSCAN core-point neighbour count.
        min_points: clusters smaller than this are noise and are absorbed by their nearest kept cluster.

    Returns:
        ``(P,)`` int64 labels in ``0..K-1``, entities ordered by centroid ``x``, then ``z``, then ``y``.
        A cloud where no cluster reaches ``min_points`` is one entity.

    Raises:
        InputError: ``points`` is not a non-empty finite ``(P, 3)`` array, or a parameter is out of range.
    """
    pts = _check_cloud(points)
    if not eps > 0:
        raise InputError(f"eps must be > 0, got {eps}")
    if min_samples < 1 or min_points < 1:
        raise InputError(f"min_samples and min_points must be >= 1, got {min_samples} and {min_points}")
    from sklearn.cluster import DBSCAN

    raw = DBSCAN(eps=eps, min_samples=min_samples).fit_predict(pts)
    ids, counts = np.unique(raw[raw >= 0], return_counts=True)
    kept = ids[counts >= min_points]
    if len(kept) == 0:
        return np.zeros(len(pts), dtype=np.int64)
    keep_mask = np.isin(raw, kept)
    labels = raw.copy()
    if not keep_mask.all():
        from scipy.spatial import cKDTree

        _, nearest = cKDTree(pts[keep_mask]).query(pts[~keep_mask])
        labels[~keep_mask] = raw[keep_mask][nearest]
    centroids = np.stack([pts[labels == k].mean(0) for k in kept])
    # Round so that float noise in centroids cannot swap the order of pieces lying side by side in z.
    key = np.round(centroids, 6)
    order = np.lexsort((key[:, 1], key[:, 2], key[:, 0]))
    remap = np.empty(int(kept.max()) + 1, dtype=np.int64)
    remap[kept[order]] = np.arange(len(kept))
    return remap[labels]


def decompose(
    points: np.ndarray,
    *,
    eps: float = 0.03,
    min_samples: int = 6,
    min_points: int = 10,
    num_points: int = 1000,
    seed: int = 0,
) -> list[np.ndarray]:
    """Split ``points (P, 3)`` into entities, each resampled to ``(num_points, 3)`` float32.

    Entities come in the order of :func:`decompose_labels`. Resampling draws without replacement when
    an entity has at least ``num_points`` points; a smaller entity keeps all its points and repeats
    randomly chosen ones. The generator is seeded with ``seed``, so the result is deterministic.

    Raises:
        InputError: empty, non-finite or wrongly shaped ``points``; ``num_points < 1``.
    """
    if num_points < 1:
        raise InputError(f"num_points must be >= 1, got {num_points}")
    labels = decompose_labels(points, eps=eps, min_samples=min_samples, min_points=min_points)
    pts = np.asarray(points, dtype=np.float32)
    rng = np.random.default_rng(seed)
    return [resample(pts[labels == k], num_points, rng) for k in range(int(labels.max()) + 1)]


def resample(points: np.ndarray, num_points: int, rng: np.random.Generator) -> np.ndarray:
    """``(num_points, 3)`` points of ``points (P, 3)``, with replacement only when ``P < num_points``."""
    n = len(points)
    if n >= num_points:
        idx = rng.choice(n, size=num_points, replace=False)
    else:
        idx = np.concatenate([np.arange(n), rng.choice(n, size=num_points - n, replace=True)])
        idx = rng.permutation(idx)
    return np.ascontiguousarray(points[idx], dtype=np.float32)


def voxel_downsample(points: np.ndarray, max_points: int) -> tuple[np.ndarray, float]:
    """Bound a cloud ``(P, 3)`` to at most ``max_points`` points by averaging the points of each voxel.

    A cloud with ``P <= max_points`` comes back unchanged (as float32), with voxel size 0. Otherwise the
    voxel edge is the smallest one (found by bisection on a grid anchored at the cloud's minimum corner,
    to within 1%) whose occupied voxels number at most ``max_points``; each occupied voxel becomes the
    mean of its points. Numpy only and sequential sums, so the result is deterministic; voxels come in
    the order of their grid index.

    Args:
        points: ``(P, 3)`` finite cloud (``np.ndarray``).
        max_points: the bound, ``>= 1``.

    Returns:
        ``(points (Q, 3) float32 with Q <= max_points, voxel edge)``.

    Raises:
        InputError: empty, non-finite or wrongly shaped ``points``; ``max_points < 1``.
    """
    if max_points < 1:
        raise InputError(f"max_points must be >= 1, got {max_points}")
    pts = _check_cloud(points)
    if len(pts) <= max_points:
        return np.ascontiguousarray(pts, dtype=np.float32), 0.0
    low = pts.min(0)
    extent = pts.max(0) - low
    span = float(extent.max())
    if span == 0.0:  # every point is the same point
        return np.ascontiguousarray(pts[:1], dtype=np.float32), 0.0
    # an edge just above the span puts every point in one voxel: always within the bound; edges are
    # searched down to span / 2**20 only, so a voxel index always fits the 21 bits _voxel_keys gives it
    fits, finest = span * (1 + 1e-6), span / 2**20
    # first guess: the edge at which a cloud filling its bounding box would occupy max_points voxels
    guess = float(np.prod(np.maximum(extent, span * 1e-3)) / max_points) ** (1 / 3)
    too_fine, edge = None, min(max(guess, finest), fits)
    while True:  # halve until the bound is exceeded (a cloud of few distinct points may never exceed it)
        if _voxel_count(pts, low, edge) > max_points:
            too_fine = edge
            break
        fits = edge
        if edge <= finest:
            break
        edge = max(edge / 2, finest)
    if too_fine is not None:
        while fits / too_fine > 1.01:
            mid = (fits * too_fine) ** 0.5
            if _voxel_count(pts, low, mid) > max_points:
                too_fine = mid
            else:
                fits = mid
    keys = _voxel_keys(pts, low, fits)
    uniq, inverse, counts = np.unique(keys, return_inverse=True, return_counts=True)
    sums = np.stack([np.bincount(inverse, weights=pts[:, a], minlength=len(uniq)) for a in range(3)], 1)
    return np.ascontiguousarray(sums / counts[:, None], dtype=np.float32), fits


def _voxel_keys(pts: np.ndarray, low: np.ndarray, edge: float) -> np.ndarray:
    """One int64 key per point: its voxel's grid index ``(i, j, k)`` packed in 21 bits each."""
    cells = np.floor((pts - low) / edge).astype(np.int64)
    return (cells[:, 0] << 42) | (cells[:, 1] << 21) | cells[:, 2]


def _voxel_count(pts: np.ndarray, low: np.ndarray, edge: float) -> int:
    keys = _voxel_keys(pts, low, edge)
    keys.sort()
    return int(1 + np.count_nonzero(keys[1:] != keys[:-1]))


def _check_cloud(points: object) -> np.ndarray:
    shape = tuple(getattr(points, "shape", ()))
    if len(shape) != 2 or shape[1] != 3:
        raise InputError(f"points must be an array of shape (P, 3), got shape {shape}")
    if shape[0] == 0:
        raise InputError("points is empty: a dough cloud needs at least one point")
    pts = np.asarray(points, dtype=np.float64)
    if not np.isfinite(pts).all():
        bad = int((~np.isfinite(pts).all(1)).sum())
        raise InputError(f"points contains NaN or infinite values ({bad} of {shape[0]} points)")
    return pts
