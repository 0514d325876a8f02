"""Scene helpers: uniformly sampled dough pieces. A scene is the concatenation of its pieces."""

from __future__ import annotations

import numpy as np

from pasta.core.errors import InputError

#: floor height of the default 64^3 grid (``Simulator.floor_y`` gives it for any grid)
FLOOR_Y = 0.02


def _rng(rng) -> np.random.Generator:
    return rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)


def box_particles(center, size, n: int, rng=None) -> np.ndarray:
    """(n, 3) float32 points uniform in the axis-aligned box of full extents ``size`` (3,) at ``center`` (3,)."""
    c, s = np.asarray(center, float), np.asarray(size, float)
    if c.shape != (3,) or s.shape != (3,) or (s <= 0).any() or n < 1:
        raise InputError(f"box_particles: center and size must be 3-vectors, size > 0, n >= 1 (got {center}, {size}, {n})")
    return (c + (_rng(rng).random((int(n), 3)) - 0.5) * s).astype(np.float32)


def sphere_particles(center, radius: float, n: int, rng=None) -> np.ndarray:
    """(n, 3) float32 points uniform in the ball of ``radius`` around ``center`` (3,)."""
    c = np.asarray(center, float)
    if c.shape != (3,) or radius <= 0 or n < 1:
        raise InputError(f"sphere_particles: center must be a 3-vector, radius > 0, n >= 1 (got {center}, {radius}, {n})")
    g = _rng(rng)
    d = g.normal(size=(int(n), 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True) + 1e-12
    r = radius * g.random(int(n)) ** (1.0 / 3.0)
    return (c + d * r[:, None]).astype(np.float32)


def crs_dough(n: int, rng=None, floor_y: float = FLOOR_Y, length: float | None = None,
              depth: float | None = None, height: float = 0.08) -> np.ndarray:
    """The CutRearrangeSpread dough: a box of length (x) U(0.2, 0.35), height 0.08, depth (z)
    U(0.06, 0.08), resting on the floor with its centre at x = 0.9 - length / 2, z = 0.5. (n, 3)."""
    g = _rng(rng)
    length = g.uniform(0.2, 0.35) if length is None else length
    depth = g.uniform(0.06, 0.08) if depth is None else depth
    center = (0.9 - length / 2, floor_y + height / 2, 0.5)
    return box_particles(center, (length, height, depth), n, g)
