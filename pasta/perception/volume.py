"""How much dough a cloud holds: the summed convex-hull volume of its pieces (m^3).

Dough is neither made nor destroyed by any skill, so a goal that holds far more or far less dough than the
observation is unreachable, whatever the plan. The estimate has to work on the clouds pasta plans from:
full simulator clouds (particles fill the volume) and completed camera views (``preprocess=camera`` fills
every column down to the table), at any point density. The convex hull of each piece does: it depends on
the piece's outline, not on how many points sample it. It over-estimates concave pieces (a rolled sheet's
ripples, pieces gathered into one), which is why the check allows a factor (``check.volume_ratio``).
"""

from __future__ import annotations

import numpy as np

__all__ = ["piece_volumes", "volume_ratio"]


def piece_volumes(points: np.ndarray, labels: np.ndarray) -> np.ndarray:
    """``(K,)`` convex-hull volume (m^3) of each piece ``k`` of ``points (P, 3)`` labelled ``labels (P,)``
    (``-1``: noise, ignored); a flat or tiny piece (no 3D hull) counts 0."""
    from scipy.spatial import ConvexHull, QhullError

    pts = np.asarray(points, dtype=np.float64)
    labels = np.asarray(labels)
    k = int(labels.max()) + 1 if labels.size else 0
    out = np.zeros(k)
    for i in range(k):
        piece = pts[labels == i]
        if len(piece) < 4:
            continue
        try:
            out[i] = ConvexHull(piece).volume
        except (QhullError, ValueError):  # all points on a plane or a line: no volume
            pass
    return out


def volume_ratio(goal: float, obs: float) -> float:
    """``goal / obs``, with ``inf`` for dough from nothing and ``0`` for no dough in the goal."""
    if obs <= 0.0:
        return float("inf") if goal > 0.0 else 1.0
    return float(goal) / float(obs)
