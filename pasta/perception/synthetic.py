"""Camera-like views of full simulator clouds, to test and measure ``pasta plan`` on real-world inputs.

``camera_view(points (P, 3), rng, ...)`` keeps what a top-down depth camera sees of the dough (the points
within ``depth`` of the highest point of each ``cell`` x ``cell`` column), resamples it to ``density``
points, adds Gaussian noise, a fraction of outliers uniform in the workspace and, optionally, the
visible table plane. The frame helpers put a workspace cloud in millimetres, a z-up frame or a camera
frame (the inverse of what ``units=``, ``up=`` and ``transform=`` undo).
"""

from __future__ import annotations

import numpy as np

from pasta.perception.preprocess import TABLE_HEIGHT

__all__ = ["top_surface", "camera_view", "camera_transform"]


def top_surface(points: np.ndarray, *, cell: float = 0.005, depth: float = 0.003) -> np.ndarray:
    """``(V, 3)`` the points of ``points (P, 3)`` within ``depth`` of the highest point of their xz cell."""
    pts = np.asarray(points, dtype=np.float64)
    cells = np.floor(pts[:, [0, 2]] / cell).astype(np.int64)
    _, inverse = np.unique(cells, axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    top = np.full(int(inverse.max()) + 1, -np.inf)
    np.maximum.at(top, inverse, pts[:, 1])
    return pts[pts[:, 1] >= top[inverse] - depth]


def camera_view(points: np.ndarray, rng: np.random.Generator, *, visible: bool = True, density: int | None = None,
                noise: float = 0.0, outliers: float = 0.0, table: int = 0, cell: float = 0.005,
                depth: float = 0.003, table_height: float = TABLE_HEIGHT) -> np.ndarray:
    """A camera-like ``(Q, 3)`` float32 view of a full dough cloud ``points (P, 3)`` (workspace frame).

    Args:
        visible: keep only the top surface (:func:`top_surface`).
        density: resample the dough to this many points (with replacement when fewer), or keep them.
        noise: standard deviation (metres) of Gaussian noise on every point.
        outliers: outlier points, as a fraction of the dough points, uniform in the unit cube.
        table: points of the table plane (at ``table_height``) visible around the dough, x in [0.05, 0.95],
            z in [0.1, 0.9], outside the dough's columns.
    """
    pts = top_surface(points, cell=cell, depth=depth) if visible else np.asarray(points, dtype=np.float64)
    if density is not None:
        pts = pts[rng.choice(len(pts), size=density, replace=density > len(pts))]
    parts = [pts]
    if table:
        occupied = {tuple(c) for c in np.floor(np.asarray(points)[:, [0, 2]] / cell).astype(np.int64)}
        cand = np.column_stack([rng.uniform(0.05, 0.95, 4 * table), np.full(4 * table, table_height),
                                rng.uniform(0.1, 0.9, 4 * table)])
        free = np.array([tuple(c) not in occupied for c in np.floor(cand[:, [0, 2]] / cell).astype(np.int64)])
        parts.append(cand[free][:table])
    out = np.concatenate(parts)
    if noise > 0:
        out = out + rng.normal(0.0, noise, out.shape)
    n_out = int(round(outliers * len(pts)))
    if n_out:
        out = np.concatenate([out, rng.uniform(0.0, 1.0, (n_out, 3))])
    return np.clip(out, 0.0, 1.0).astype(np.float32)


def camera_transform(height: float = 1.2, yaw: float = 0.3, centre: tuple[float, float] = (0.5, 0.5)) -> np.ndarray:
    """``(4, 4)`` camera-to-workspace matrix of a camera ``height`` above the workspace centre looking down
    (camera z along -y), turned by ``yaw`` radians about the vertical; points in the camera frame are
    ``inverse(T) @ workspace``."""
    c, s = np.cos(yaw), np.sin(yaw)
    # camera axes in workspace coordinates: x right, y forward (in the table plane), z down
    x_axis = np.array([c, 0.0, -s])
    y_axis = np.array([s, 0.0, c])
    z_axis = np.array([0.0, -1.0, 0.0])
    t = np.eye(4)
    t[:3, :3] = np.column_stack([x_axis, y_axis, z_axis])
    t[:3, 3] = [centre[0], height, centre[1]]
    return t
