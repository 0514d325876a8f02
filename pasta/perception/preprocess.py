"""Preprocessing of a camera cloud before decomposition: crop, table removal, outlier removal, completion.

A pure stage: ``preprocess(points (P, 3) workspace frame, config) -> Preprocessed``; every step is
optional and seeded, and points that a step drops are dropped (never merged into a piece):

1. ``crop``: keep the points inside the workspace box ``[crop_low, crop_high]`` (default the unit cube).
2. ``table``: ``height`` drops the points below ``table_height + table_margin``; ``ransac`` fits the
   lowest dominant plane (scikit-learn's RANSAC on ``y = a x + b z + c``), drops the points within
   ``table_margin`` of it or below it, and uses its height as the table height of step 4.
3. ``outliers``: ``statistical`` drops the points whose mean distance to their ``outlier_k`` nearest
   neighbours exceeds the cloud's mean of that distance by ``outlier_std`` standard deviations (scipy's
   cKDTree).
4. ``complete``: ``fill`` completes a top-down view: every kept point gets ``ceil((y - table) / fill_spacing)``
   points spread evenly below it, down to the table height (the dough rests on the table), so a visible
   top surface becomes a solid piece with the centroid and volume of the full one. Points already at
   the table get none.

The counts of each step are returned for the ``note:`` line and ``plan.json``.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

from pasta.core.errors import InputError

__all__ = ["PreprocessConfig", "Preprocessed", "preprocess", "PRESETS", "TABLE_HEIGHT"]

#: the height of the table the dough rests on, in pasta's workspace: the simulator's floor
#: (``pasta.sim.Simulator.floor_y`` = 1.28 cells of the 64^3 grid = 0.02)
TABLE_HEIGHT = 0.02

TABLE_MODES = ("none", "height", "ransac")
OUTLIER_MODES = ("none", "statistical")
COMPLETE_MODES = ("none", "fill")


@dataclass(frozen=True)
class PreprocessConfig:
    """Settings of :func:`preprocess` (``preprocess.KEY=VALUE`` on ``pasta plan``)."""

    crop: bool = False
    crop_low: tuple[float, float, float] = (0.0, 0.0, 0.0)
    crop_high: tuple[float, float, float] = (1.0, 1.0, 1.0)
    table: str = "none"
    table_height: float = TABLE_HEIGHT
    table_margin: float = 0.006
    ransac_trials: int = 200
    outliers: str = "none"
    outlier_k: int = 8
    outlier_std: float = 2.0
    complete: str = "none"
    fill_spacing: float = 0.005
    seed: int = 0

    def __post_init__(self) -> None:
        for key, value, modes in (("table", self.table, TABLE_MODES), ("outliers", self.outliers, OUTLIER_MODES),
                                  ("complete", self.complete, COMPLETE_MODES)):
            if value not in modes:
                raise InputError(f"preprocess.{key}={value}: allowed {', '.join(modes)}")
        for key in ("table_margin", "fill_spacing", "outlier_std"):
            if not (np.isfinite(getattr(self, key)) and getattr(self, key) > 0):
                raise InputError(f"preprocess.{key}={getattr(self, key)}: must be a finite number > 0")
        if not np.isfinite(self.table_height):
            raise InputError(f"preprocess.table_height={self.table_height}: must be a finite number")
        if self.outlier_k < 1 or self.ransac_trials < 1:
            raise InputError("preprocess.outlier_k and preprocess.ransac_trials must be >= 1")
        low, high = np.asarray(self.crop_low, float), np.asarray(self.crop_high, float)
        if low.shape != (3,) or high.shape != (3,) or not (np.isfinite(low).all() and np.isfinite(high).all()
                                                           and (low < high).all()):
            raise InputError(f"preprocess.crop_low/crop_high {low.tolist()} / {high.tolist()}: three finite numbers each, "
                             "low < high")

    @property
    def active(self) -> bool:
        return self.crop or self.table != "none" or self.outliers != "none" or self.complete != "none"

    def to_dict(self) -> dict:
        return {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(self).items()}


#: ``preprocess=NAME`` presets (single keys override them)
PRESETS = {
    "none": {},
    # a top-down depth camera: the workspace crop, the table by height, isolated points, fill to the table
    "camera": {"crop": True, "table": "height", "outliers": "statistical", "complete": "fill"},
}


@dataclass
class Preprocessed:
    """The result of :func:`preprocess`.

    Attributes:
        points: ``(Q, 3)`` float32 the cloud to decompose (kept points first, then completion points).
        kept: ``(P,)`` bool, which input points survived (the first ``kept.sum()`` rows of ``points``).
        table_height: the table height used (fitted by ``ransac``), or None without table removal.
        counts: points dropped/added per step.
    """

    points: np.ndarray
    kept: np.ndarray
    table_height: float | None
    counts: dict = field(default_factory=dict)


def preprocess(points: np.ndarray, config: PreprocessConfig | None = None) -> Preprocessed:
    """Run the configured steps on ``points (P, 3)`` (workspace frame: metres, y up); deterministic."""
    cfg = config or PreprocessConfig()
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 3 or not np.isfinite(pts).all():
        raise InputError(f"preprocess expects a finite (P, 3) cloud, got shape {pts.shape}")
    kept = np.ones(len(pts), bool)
    counts: dict[str, int] = {}
    if cfg.crop:
        inside = ((pts >= np.asarray(cfg.crop_low)) & (pts <= np.asarray(cfg.crop_high))).all(1)
        counts["cropped"] = int((~inside).sum())
        kept &= inside
    table = None
    if cfg.table == "height":
        table = float(cfg.table_height)
        low = pts[:, 1] < table + cfg.table_margin
        counts["table"] = int((low & kept).sum())
        kept &= ~low
    elif cfg.table == "ransac":
        on_table, table = _ransac_table(pts[kept], cfg)
        idx = np.flatnonzero(kept)
        counts["table"] = int(on_table.sum())
        kept[idx[on_table]] = False
    if cfg.outliers == "statistical" and kept.sum() > cfg.outlier_k:
        idx = np.flatnonzero(kept)
        bad = _statistical_outliers(pts[idx], cfg.outlier_k, cfg.outlier_std)
        counts["outliers"] = int(bad.sum())
        kept[idx[bad]] = False
    out = pts[kept]
    if cfg.complete == "fill" and len(out):
        base = cfg.table_height if table is None else table
        fill = _fill_to_table(out, base, cfg.fill_spacing)
        counts["filled"] = len(fill)
        out = np.concatenate([out, fill])
    return Preprocessed(np.ascontiguousarray(out, dtype=np.float32), kept, table, counts)


def _statistical_outliers(pts: np.ndarray, k: int, std_ratio: float) -> np.ndarray:
    """``(P,)`` bool: mean distance to the ``k`` nearest neighbours above mean + ``std_ratio`` * std."""
    from scipy.spatial import cKDTree

    dist, _ = cKDTree(pts).query(pts, k=k + 1)  # the first neighbour is the point itself
    mean = dist[:, 1:].mean(1)
    return mean > mean.mean() + std_ratio * mean.std()


def _ransac_table(pts: np.ndarray, cfg: PreprocessConfig) -> tuple[np.ndarray, float]:
    """Points on or below the table plane, and the plane's height at the cloud's centre (xz)."""
    if len(pts) < 3:
        return np.zeros(len(pts), bool), float(cfg.table_height)
    from sklearn.linear_model import RANSACRegressor

    xz, y = pts[:, [0, 2]], pts[:, 1]
    # the table is the LOWEST dominant plane: fit, and while many points lie below the fit (it found a
    # dough top), refit on the points below it
    candidates = np.ones(len(pts), bool)
    for _ in range(4):
        if candidates.sum() < 3:
            break
        model = RANSACRegressor(residual_threshold=cfg.table_margin, max_trials=cfg.ransac_trials,
                                random_state=cfg.seed)
        model.fit(xz[candidates], y[candidates])
        resid = y - model.predict(xz)
        below = resid < -cfg.table_margin
        if below.sum() <= 0.02 * len(pts):
            break
        candidates = below
    slope = np.abs(model.estimator_.coef_)
    if slope.max() > 0.2:  # steeper than ~11 degrees: not a table seen from above
        raise InputError(f"preprocess.table=ransac: the dominant plane is tilted (slopes {slope.round(3).tolist()} in "
                         "x, z); is the cloud y up (up=, transform=)?")
    centre = xz.mean(0, keepdims=True)
    return resid < cfg.table_margin, float(model.predict(centre)[0])


def _fill_to_table(pts: np.ndarray, table: float, spacing: float) -> np.ndarray:
    """``(F, 3)`` points below each point of ``pts (P, 3)``, evenly spaced down to ``table``."""
    height = pts[:, 1] - table
    n = np.where(height > 0, np.ceil(height / spacing), 0).astype(np.int64)
    total = int(n.sum())
    if total == 0:
        return np.zeros((0, 3))
    owner = np.repeat(np.arange(len(pts)), n)
    # the j-th of n points below a point sits at height (j + 0.5) / n of its column: evenly in volume
    first = np.repeat(np.cumsum(n) - n, n)
    j = np.arange(total) - first
    frac = (j + 0.5) / n[owner]
    out = pts[owner].copy()
    out[:, 1] = table + frac * height[owner]
    return out
