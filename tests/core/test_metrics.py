"""Metric tests: EMD of shifted and identical clouds, normalised improvement, Chamfer basics."""

from __future__ import annotations

import numpy as np
import pytest

from pasta.core.errors import InputError
from pasta.core.metrics import chamfer, emd, normalized_improvement


def _cloud(n: int = 800, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).uniform(0.3, 0.6, size=(n, 3)).astype(np.float32)


@pytest.mark.parametrize("d", [0.01, 0.05, 0.2])
def test_emd_of_shifted_copy_is_the_shift(d: float) -> None:
    a = _cloud()
    direction = np.array([1.0, 2.0, -2.0]) / 3.0
    b = a + d * direction
    assert emd(a, b, n=500, seed=3) == pytest.approx(d, rel=1e-4, abs=1e-6)


def test_emd_of_shifted_copy_different_sizes_is_close_to_shift() -> None:
    a = _cloud(2000, 1)
    b = _cloud(1500, 2) + np.array([0.1, 0.0, 0.0])
    # different samples of the same distribution: EMD >= shift, close to it for large n
    value = emd(a, b, n=500, seed=0)
    assert 0.1 <= value + 1e-6 < 0.13


def test_emd_identical_clouds_is_zero() -> None:
    a = _cloud()
    assert emd(a, a.copy(), n=500) == pytest.approx(0.0, abs=1e-9)


def test_emd_is_symmetric_and_seeded() -> None:
    a, b = _cloud(seed=1), _cloud(seed=2)
    assert emd(a, b, seed=7) == pytest.approx(emd(b, a, seed=7), abs=1e-9)
    assert emd(a, b, seed=7) == emd(a, b, seed=7)


def test_initial_state_normalised_improvement_is_zero() -> None:
    init, goal = _cloud(seed=1), _cloud(seed=2) + 0.1
    e0 = emd(init, goal)
    assert normalized_improvement(e0, emd(init, goal)) == 0.0
    assert normalized_improvement(e0, 0.0) == 1.0
    assert normalized_improvement(e0, 2 * e0) == pytest.approx(-1.0)


def test_normalised_improvement_rejects_zero_initial_emd() -> None:
    with pytest.raises(InputError, match="initial EMD"):
        normalized_improvement(0.0, 0.1)


def test_emd_rejects_bad_clouds() -> None:
    with pytest.raises(InputError):
        emd(np.zeros((10, 2)), np.zeros((10, 3)))
    with pytest.raises(InputError):
        emd(np.full((10, 3), np.nan), np.zeros((10, 3)))


def test_chamfer_of_identical_is_zero_and_shift_is_two_d_squared() -> None:
    a = _cloud(200)
    assert float(chamfer(a, a)) == pytest.approx(0.0, abs=1e-6)
    # a flat cloud (x = 0) shifted along its normal: every nearest neighbour is the shifted twin
    a[:, 0] = 0.0
    b = a + np.array([1.0, 0.0, 0.0], dtype=np.float32)
    assert float(chamfer(a, b)) == pytest.approx(2.0, rel=1e-4)
