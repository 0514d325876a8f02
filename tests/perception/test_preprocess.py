"""Preprocessing of camera clouds: crop, table removal, statistical outliers (dropped), fill to the table."""

from __future__ import annotations

import numpy as np
import pytest

from pasta.core.decompose import decompose_labels
from pasta.core.errors import InputError
from pasta.perception import PRESETS, TABLE_HEIGHT, PreprocessConfig, preprocess
from pasta.perception.synthetic import camera_view, top_surface


def _box(rng, centre, size, n):
    """Uniform points in a box resting on the table (centre x, z; size x, y, z)."""
    lo = np.array([centre[0] - size[0] / 2, TABLE_HEIGHT, centre[1] - size[2] / 2])
    return lo + rng.uniform(0, 1, (n, 3)) * np.array(size)


def _scene(seed=0):
    rng = np.random.default_rng(seed)
    return np.concatenate([_box(rng, (0.3, 0.5), (0.1, 0.08, 0.07), 4000),
                           _box(rng, (0.7, 0.4), (0.12, 0.02, 0.1), 3000)])


def _centroids(pts):
    lab = decompose_labels(pts, min_points=50)
    return np.stack([pts[lab == k].mean(0) for k in range(int(lab.max()) + 1)])


def test_top_surface_keeps_the_top():
    full = _scene()
    top = top_surface(full)
    assert len(top) < len(full) / 3
    # the thin piece's top is at 0.04; only sparse columns at the boxes' edges reach lower
    assert np.median(top[:, 1]) > 0.035 and (top[:, 1] < TABLE_HEIGHT + 0.01).mean() < 0.05


def test_fill_restores_centroids_of_a_top_down_view():
    full = _scene()
    view = camera_view(full, np.random.default_rng(1), noise=0.002)
    seen, want = _centroids(view), _centroids(full)
    assert np.abs(seen[:, 1] - want[:, 1]).max() > 0.015  # the visible surface sits ~2 cm too high
    done = preprocess(view, PreprocessConfig(complete="fill"))
    assert done.kept.all() and done.counts["filled"] > 5 * len(view)
    np.testing.assert_allclose(_centroids(done.points), want, atol=0.004)


def test_camera_preset_drops_table_and_outliers():
    full = _scene()
    rng = np.random.default_rng(2)
    view = camera_view(full, rng, noise=0.002, outliers=0.01, table=3000)
    n_dough = len(camera_view(full, np.random.default_rng(2), noise=0.002))
    done = preprocess(view, PreprocessConfig(**PRESETS["camera"]))
    # the table rows (after the dough rows) go, and so do most of the outliers (the last rows)
    table = slice(n_dough, len(view) - int(round(0.01 * n_dough)))
    assert done.kept[table].mean() < 0.01  # the 2 mm noise lifts a few table points above the 6 mm margin
    assert done.kept[table.stop:].mean() < 0.3  # an outlier inside a piece cannot be told apart
    assert done.kept[:n_dough].mean() > 0.9
    assert len(_centroids(done.points)) == 2
    np.testing.assert_allclose(_centroids(done.points), _centroids(full), atol=0.006)


def test_ransac_finds_the_table_and_refuses_a_wall():
    full = _scene()
    view = camera_view(full, np.random.default_rng(3), noise=0.001, table=3000)
    done = preprocess(view, PreprocessConfig(table="ransac"))
    assert abs(done.table_height - TABLE_HEIGHT) < 0.002
    assert (done.points[:, 1] > TABLE_HEIGHT + 0.004).all()
    wall = view[:, [1, 0, 2]]  # the table turned vertical: the plane is x = const
    with pytest.raises(InputError, match="tilted"):
        preprocess(wall, PreprocessConfig(table="ransac"))


def test_crop_and_determinism():
    view = camera_view(_scene(), np.random.default_rng(4), outliers=0.05)
    cfg = PreprocessConfig(crop=True, crop_low=(0.2, 0.0, 0.3), crop_high=(0.5, 1.0, 0.7), outliers="statistical",
                           complete="fill")
    a, b = preprocess(view, cfg), preprocess(view, cfg)
    assert np.array_equal(a.points, b.points) and np.array_equal(a.kept, b.kept)
    kept = view[a.kept]
    assert (kept[:, 0] <= 0.5).all() and (kept[:, 0] >= 0.2).all() and a.counts["cropped"] > 0


def test_bad_settings():
    with pytest.raises(InputError, match="preprocess.table=floor"):
        PreprocessConfig(table="floor")
    with pytest.raises(InputError, match="fill_spacing"):
        PreprocessConfig(fill_spacing=0.0)
    with pytest.raises(InputError, match="crop_low"):
        PreprocessConfig(crop_low=(1, 0, 0))
