"""Bounded inputs (issue 21): voxel downsampling before DBSCAN."""

import numpy as np
import pytest

from pasta.core.decompose import decompose, voxel_downsample
from pasta.core.errors import InputError


def dense_pieces(n: int, seed: int = 0) -> np.ndarray:
    """Two boxes (dough pieces) 0.3 apart, ``n`` points in all."""
    rng = np.random.default_rng(seed)
    right = rng.uniform([0.6, 0.0, 0.45], [0.9, 0.08, 0.52], (n - n // 3, 3))
    left = rng.uniform([0.2, 0.0, 0.45], [0.3, 0.08, 0.52], (n // 3, 3))
    return np.concatenate([right, left]).astype(np.float32)


def test_small_clouds_come_back_unchanged():
    pts = dense_pieces(3000)
    small, voxel = voxel_downsample(pts, 3000)
    assert voxel == 0.0 and small.dtype == np.float32 and np.array_equal(small, pts)


@pytest.mark.parametrize("bound", [5000, 1000, 64])
def test_large_clouds_are_bounded_close_to_the_bound(bound):
    pts = dense_pieces(200_000)
    small, voxel = voxel_downsample(pts, bound)
    assert len(small) <= bound and len(small) > 0.6 * bound  # the smallest voxel within 1% that fits
    assert voxel > 0 and np.isfinite(small).all()
    assert (small.min(0) >= pts.min(0) - 1e-6).all() and (small.max(0) <= pts.max(0) + 1e-6).all()


def test_downsampling_is_deterministic_and_keeps_the_pieces():
    pts = dense_pieces(100_000)
    a, va = voxel_downsample(pts, 8000)
    b, vb = voxel_downsample(pts.copy(), 8000)
    assert va == vb and np.array_equal(a, b)
    assert va < 0.03  # well below DBSCAN's eps, so clustering sees the same pieces
    assert len(decompose(a, min_points=50, num_points=200)) == 2


def test_degenerate_clouds():
    same, voxel = voxel_downsample(np.full((50, 3), 0.5, np.float32), 10)
    assert same.shape == (1, 3) and voxel == 0.0 and np.allclose(same, 0.5)
    two = np.array([[0.1, 0.1, 0.1], [0.9, 0.9, 0.9]] * 30, np.float32)  # 2 distinct points, 60 rows
    small, _ = voxel_downsample(two, 10)
    assert len(small) == 2 and np.allclose(np.sort(small[:, 0]), [0.1, 0.9])
    line = np.stack([np.linspace(0, 1, 100_000)] + [np.zeros(100_000)] * 2, 1)  # a flat, thin cloud
    assert 0.9 * 500 < len(voxel_downsample(line, 500)[0]) <= 500


def test_bad_arguments():
    with pytest.raises(InputError, match="max_points must be >= 1"):
        voxel_downsample(dense_pieces(100), 0)
    with pytest.raises(InputError, match="NaN"):
        voxel_downsample(np.full((5, 3), np.nan), 2)
