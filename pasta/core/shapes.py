"""Shape vocabulary used in every docstring of the project.

- ``B``: batch (planner samples, training examples)
- ``K``: entities (dough pieces) in a set; ``N`` the entities a skill consumes (N_k), ``M`` those it
  produces (M_k), ``G`` the entities of the goal
- ``P``: points per point cloud; ``T`` tool points
- ``D``: entity latent size, ``D = Z + 3``: the shape code ``z`` (``Z`` numbers) followed by the
  centroid ``t`` (x, y, z)
- ``H``: planning horizon (skill steps)
- ``A``: action size of a tool

Tensors are ``torch.Tensor`` unless a docstring says ``np.ndarray``. Point clouds are float32, metres
in a unit-cube workspace, y up.
"""

from __future__ import annotations

from typing import Any


def check_points(points: Any, name: str = "points", *, min_points: int = 1) -> Any:
    """Validate a point cloud ``(P, 3)`` (numpy or torch) and return it unchanged.

    Raises:
        InputError: wrong shape, fewer than ``min_points`` points, or non-finite values.
    """
    from pasta.core.errors import InputError

    shape = tuple(getattr(points, "shape", ()))
    if len(shape) != 2 or shape[1] != 3:
        raise InputError(f"{name} must have shape (P, 3), got {shape}")
    if shape[0] < min_points:
        raise InputError(f"{name} has {shape[0]} points; at least {min_points} needed")
    if not _all_finite(points):
        raise InputError(f"{name} contains NaN or infinite values")
    return points


def as_points(points: Any, name: str = "points") -> Any:
    """``points`` as a validated float64 ``(P, 3)`` ``np.ndarray`` (see :func:`check_points`)."""
    import numpy as np

    return check_points(np.asarray(points, dtype=np.float64), name)


def check_latents(latents: Any, name: str, *, dim: int | None = None, ndim: int = 2) -> Any:
    """Validate a latent tensor whose last axis is ``D`` (e.g. ``(K, D)``) and return it unchanged."""
    from pasta.core.errors import InputError

    shape = tuple(getattr(latents, "shape", ()))
    if len(shape) != ndim:
        raise InputError(f"{name} must have {ndim} axes (..., D), got shape {shape}")
    if dim is not None and shape[-1] != dim:
        raise InputError(f"{name} has latent size {shape[-1]}, expected D = {dim}")
    if not _all_finite(latents):
        raise InputError(f"{name} contains NaN or infinite values")
    return latents


def _all_finite(array: Any) -> bool:
    if hasattr(array, "isfinite"):  # torch
        return bool(array.isfinite().all())
    import numpy as np

    arr = np.asarray(array, dtype=float)
    return bool(np.isfinite(arr).all()) if arr.size else True

