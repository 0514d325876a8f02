import numpy as np
import pytest

from pasta.core.decompose import decompose, decompose_labels, resample
from pasta.core.errors import InputError


def box(rng, n, lo, hi):
    return rng.uniform(lo, hi, (n, 3))


@pytest.fixture
def two_boxes():
    rng = np.random.default_rng(0)
    right = box(rng, 600, [0.6, 0.03, 0.45], [0.75, 0.11, 0.52])
    left = box(rng, 400, [0.2, 0.03, 0.45], [0.3, 0.11, 0.52])
    return np.concatenate([right, left]).astype(np.float32)


def test_two_boxes_give_two_entities_left_first(two_boxes):
    entities = decompose(two_boxes, num_points=500)
    assert len(entities) == 2
    assert all(e.shape == (500, 3) and e.dtype == np.float32 for e in entities)
    assert entities[0][:, 0].max() < 0.31 and entities[1][:, 0].min() > 0.59


def test_order_does_not_depend_on_point_order(two_boxes):
    shuffled = two_boxes[np.random.default_rng(1).permutation(len(two_boxes))]
    a, b = decompose_labels(two_boxes), decompose_labels(shuffled)
    assert np.bincount(a).tolist() == np.bincount(b).tolist() == [400, 600]


def test_same_x_ordered_by_z():
    rng = np.random.default_rng(2)
    near_z = box(rng, 300, [0.4, 0.03, 0.2], [0.5, 0.1, 0.3])
    far_z = near_z + [0.0, 0.0, 0.5]  # same centroid x: z decides
    labels = decompose_labels(np.concatenate([far_z, near_z]))
    assert (labels[300:] == 0).all() and (labels[:300] == 1).all()


def test_noise_joins_nearest_kept_cluster(two_boxes):
    stray = np.array([[0.34, 0.07, 0.48], [0.36, 0.07, 0.48], [0.56, 0.07, 0.48]], np.float32)  # tiny clusters / noise
    pts = np.concatenate([two_boxes, stray])
    labels = decompose_labels(pts, min_points=10)
    assert labels.max() == 1 and len(labels) == len(pts)
    assert labels[-3] == 0 and labels[-2] == 0 and labels[-1] == 1


def test_small_cluster_below_min_points_is_noise(two_boxes):
    rng = np.random.default_rng(3)
    crumb = box(rng, 8, [0.9, 0.03, 0.48], [0.91, 0.04, 0.49])  # dense but only 8 points
    pts = np.concatenate([two_boxes, crumb])
    assert decompose_labels(pts, min_points=10).max() == 1
    assert decompose_labels(pts, min_points=5).max() == 2


def test_deterministic_and_seeded(two_boxes):
    a, b = decompose(two_boxes, seed=7), decompose(two_boxes, seed=7)
    assert all(np.array_equal(x, y) for x, y in zip(a, b))
    c = decompose(two_boxes, seed=8)
    assert not np.array_equal(a[0], c[0])


def test_resample_replacement_only_when_needed():
    pts = np.arange(30, dtype=np.float32).reshape(10, 3)
    rng = np.random.default_rng(0)
    down = resample(pts, 6, rng)
    assert len(np.unique(down[:, 0])) == 6
    up = resample(pts, 25, rng)
    assert up.shape == (25, 3) and set(np.unique(up[:, 0])) == set(pts[:, 0])


def test_all_noise_is_one_entity():
    pts = np.random.default_rng(0).uniform(0, 1, (20, 3))
    assert len(decompose(pts, num_points=20)) == 1


@pytest.mark.parametrize(
    "points, message",
    [
        (np.zeros((0, 3)), "empty"),
        (np.zeros((10, 2)), "shape"),
        (np.zeros(30), "shape"),
        (np.array([[0.0, np.nan, 0.0]] * 10), "NaN"),
    ],
)
def test_bad_clouds_raise_input_error(points, message):
    with pytest.raises(InputError, match=message):
        decompose(points)
