"""save_summary: PNG output for a toy episode and input validation."""

import numpy as np
import pytest
from matplotlib.image import imread

from pasta.core.errors import InputError
from pasta.execute.summary import save_summary

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def box(rng, centre, n=200, size=(0.1, 0.05, 0.1)):
    return np.asarray(centre) + (rng.random((n, 3)) - 0.5) * np.asarray(size)


def episode(rng, steps):
    initial = box(rng, (0.5, 0.025, 0.5), size=(0.3, 0.05, 0.2))
    subgoals = [
        (f"{i + 1}. cut", [box(rng, (0.4, 0.025, 0.5)), box(rng, (0.6, 0.025, 0.5))]) for i in range(steps)
    ]
    goal = box(rng, (0.5, 0.03, 0.4))
    final = box(rng, (0.52, 0.03, 0.42))
    return dict(initial=initial, goal=goal, final=final, subgoals=subgoals)


def test_writes_png_sized_by_panels(tmp_path):
    rng = np.random.default_rng(0)
    path = save_summary(tmp_path / "a" / "b" / "three.png", title="toy episode", **episode(rng, 3))
    assert path == tmp_path / "a" / "b" / "three.png"
    assert path.read_bytes()[:8] == PNG_SIGNATURE
    assert path.stat().st_size < 300_000
    h3, w3 = imread(path).shape[:2]
    assert w3 > h3

    h1, w1 = imread(save_summary(tmp_path / "one.png", **episode(rng, 1))).shape[:2]
    assert w3 > w1
    assert abs((w3 - w1) - 2 * (w1 / 3)) <= 2  # 5 vs 3 panels of equal width


def test_accepts_float32_and_no_steps(tmp_path):
    rng = np.random.default_rng(1)
    ep = episode(rng, 0)
    ep = {k: v.astype(np.float32) if isinstance(v, np.ndarray) else v for k, v in ep.items()}
    assert save_summary(str(tmp_path / "zero.png"), **ep).read_bytes()[:8] == PNG_SIGNATURE


@pytest.mark.parametrize("name", ["initial", "goal", "final"])
@pytest.mark.parametrize("bad", ["nan", "shape", "empty"])
def test_bad_cloud_names_argument(tmp_path, name, bad):
    ep = episode(np.random.default_rng(2), 1)
    if bad == "nan":
        ep[name] = ep[name].copy()
        ep[name][3, 1] = np.nan
    elif bad == "shape":
        ep[name] = ep[name][:, :2]
    else:
        ep[name] = np.zeros((0, 3))
    with pytest.raises(InputError, match=name):
        save_summary(tmp_path / "x.png", **ep)
    assert not (tmp_path / "x.png").exists()


@pytest.mark.parametrize(
    "subgoals",
    [
        "1. cut",  # not a list
        [("1. cut",)],  # not a pair
        [(3, [np.zeros((5, 3))])],  # label not a str
        [("1. cut", np.zeros((5, 3)))],  # clouds is one array, not a list
        [("1. cut", [])],  # no pieces
        [("1. cut", [np.zeros((5, 2))])],  # piece of wrong shape
        [("1. cut", [np.full((5, 3), np.inf)])],  # non-finite piece
    ],
)
def test_bad_subgoals_names_argument(tmp_path, subgoals):
    ep = episode(np.random.default_rng(3), 0)
    ep["subgoals"] = subgoals
    with pytest.raises(InputError, match="subgoals"):
        save_summary(tmp_path / "x.png", **ep)
