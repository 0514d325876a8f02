"""A goal with far more or far less dough than the observation is refused as unreachable (exit 3) before any
planning, in ``pasta plan``, ``pasta run`` and ``pasta eval`` (issue 41; ``check.volume_ratio``)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from pasta.cli import main
from pasta.config.run import CheckConfig, PerceptionConfig
from pasta.core.errors import ConfigError, UnreachableGoalError
from pasta.execute.episode import check_volumes
from pasta.perception.volume import piece_volumes


def _box(rng, low, high, n=3000):
    """``n`` points uniform in the box, its 8 corners among them (a sampled outline at any density)."""
    low, high = np.asarray(low), np.asarray(high)
    corners = np.array([[(low, high)[(i >> d) & 1][d] for d in range(3)] for i in range(8)])
    return np.concatenate([corners, rng.uniform(low, high, (n - 8, 3))]).astype(np.float32)


def _scaled(points: np.ndarray, factor: float) -> np.ndarray:
    """``points`` scaled by ``factor`` in every direction about their centroid, resting on the same floor."""
    c = points.mean(0)
    out = (points - c) * factor + c
    out[:, 1] += points[:, 1].min() - out[:, 1].min()
    return out.astype(np.float32)


def test_piece_volumes_are_the_convex_hulls_and_do_not_depend_on_density():
    rng = np.random.default_rng(0)
    a, b = _box(rng, (0.2, 0.0, 0.2), (0.3, 0.05, 0.3)), _box(rng, (0.6, 0.0, 0.6), (0.7, 0.02, 0.8), n=300)
    v = piece_volumes(np.concatenate([a, b]), np.repeat([0, 1], [len(a), len(b)]))
    assert v[0] == pytest.approx(0.1 * 0.05 * 0.1, rel=1e-4) and v[1] == pytest.approx(0.1 * 0.02 * 0.2, rel=1e-4)
    flat = np.column_stack([rng.uniform(0, 1, 50), np.zeros(50), rng.uniform(0, 1, 50)])
    assert piece_volumes(flat, np.zeros(50, int))[0] == 0.0  # a plane holds no dough


@pytest.mark.parametrize("factor", [0.4, 1.48])  # 6 % and 3.2 times the volume: both refused
def test_a_goal_far_from_the_observed_volume_is_refused_both_ways(factor):
    rng = np.random.default_rng(1)
    obs = _box(rng, (0.4, 0.0, 0.4), (0.55, 0.04, 0.6))
    clouds = {"obs": obs, "goal": _scaled(obs, factor)}
    labels = {k: np.zeros(len(v), int) for k, v in clouds.items()}
    with pytest.raises(UnreachableGoalError, match=r"times the observed dough .*\(check.volume_ratio\)"):
        check_volumes(clouds, labels, CheckConfig(), PerceptionConfig())
    # the factor is a setting: a looser one lets the same goal through
    vol = check_volumes(clouds, labels, CheckConfig(volume_ratio=20.0), PerceptionConfig())
    assert vol["goal"] / vol["obs"] == pytest.approx(factor ** 3, rel=0.02)


def test_the_volume_ratio_setting_is_checked():
    with pytest.raises(ConfigError, match="check.volume_ratio"):
        CheckConfig(volume_ratio=0.9)


@pytest.fixture
def crs_goal_scaled(monkeypatch):
    """Every crs instance's goal scaled to 6 % of its volume."""
    from pasta.tasks.base import Task

    original = Task.instance

    def instance(self, seed, **kw):
        inst = original(self, seed, **kw)
        return dataclasses.replace(inst, goal_state=_scaled(np.asarray(inst.goal_state), 0.4))

    monkeypatch.setattr(Task, "instance", instance)


def test_pasta_plan_refuses_a_goal_with_6_percent_of_the_dough(tmp_path, capsys):
    from pasta.tasks import get_task

    inst = get_task("crs").instance(1000)
    for name, factor in (("small", 0.4), ("large", 1.48)):
        np.save(tmp_path / "obs.npy", inst.init_points)
        np.save(tmp_path / f"{name}.npy", _scaled(inst.init_points, factor))
        code = main(["plan", f"obs={tmp_path / 'obs.npy'}", f"goal={tmp_path / f'{name}.npy'}",
                     f"out={tmp_path / name}", "check.box_margin=1"])
        err = capsys.readouterr().err.strip().splitlines()
        assert code == 3, err
        assert err[-1].startswith("pasta plan: error: the goal holds") and "check.volume_ratio" in err[-1]
        assert not (tmp_path / name / "plan.json").exists()


@pytest.mark.sim
def test_pasta_run_and_eval_refuse_it_too(tmp_path, capsys, crs_goal_scaled):
    assert main(["run", "task=crs", "seed=1000"]) == 3
    assert "pasta run: error: the goal holds 0.0" in capsys.readouterr().err
    assert main(["eval", "task=crs", "num=1", f"out={tmp_path}"]) == 3
    err = capsys.readouterr().err
    assert "seed 1000: refused, UnreachableGoalError: the goal holds 0.0" in err
