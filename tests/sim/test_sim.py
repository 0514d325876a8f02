"""Acceptance tests of the dough simulator (issue 3)."""

from __future__ import annotations

import numpy as np
import pytest

from pasta.core.errors import ConfigError
from pasta.plugins import get_plugins
from pasta.sim import (
    SimConfig,
    SimState,
    SimulationDiverged,
    box_particles,
    render_png,
    sphere_particles,
)

pytestmark = pytest.mark.sim


def test_rest_200_steps(fresh, helpers):
    sim = fresh
    sim.reset(helpers.dough(sim), seed=0)
    c0 = sim.particles().mean(0)
    for _ in range(200):
        sim.step()
    p = sim.particles()
    assert p.shape == (3000, 3)
    assert np.isfinite(p).all()
    assert np.linalg.norm(p.mean(0) - c0) < 2e-3
    assert sim.check() == 0
    assert sim.step_count == 200


def test_knife_cuts_in_two(fresh, helpers):
    sim = fresh
    length = 0.3
    sim.reset(helpers.dough(sim, seed=1, length=length), seed=0)
    assert helpers.n_clusters(sim.observe().dough) == 1
    cut_x = 0.9 - length / 2 - 0.03
    sim.set_tool_pose("knife", (cut_x, sim.floor_y + 0.08 + 0.1 + 0.01, 0.5))
    for _ in range(10):  # press down to the floor
        sim.step({"knife": np.array([0.0, -1.0])})
    for _ in range(6):  # then sideways, pushing the left part away
        sim.step({"knife": np.array([-0.5, 0.0])})
    for _ in range(10):  # lift out
        sim.step({"knife": np.array([0.0, 1.0])})
    sim.park_tool("knife")
    for _ in range(5):
        sim.step()
    helpers.snapshot(sim, "cut")
    obs = sim.observe()
    assert obs.dough.shape == (1000, 3)
    assert helpers.n_clusters(obs.dough) == 2


def test_roller_flattens(fresh, helpers):
    sim = fresh
    sim.reset(helpers.dough(sim, seed=2, length=0.24, shift_x=-0.15), seed=0)
    p = sim.particles()
    h0 = np.percentile(p[:, 1], 95) - sim.floor_y
    foot0 = np.ptp(p[:, 0]) * np.ptp(p[:, 2])
    left = p[:, 0].min()
    r = 0.03
    sim.set_tool_pose("roller", (left + 0.04, sim.floor_y + 0.08 + r + 0.005, 0.5))
    target_y = sim.floor_y + 0.035 + r
    for _ in range(40):  # press while rolling forth and back
        y = sim.tool_pose("roller")[1]
        dy = np.clip((target_y - y) / 0.005, -1, 1)
        sim.step({"roller": np.array([0.0, 0.0, dy, 0.0])})
        if abs(y - target_y) < 1e-4:
            break
    for sweep in range(4):  # roll over the whole piece, back and forth
        direction = 1.0 if sweep % 2 == 0 else -1.0
        for _ in range(40):
            xs = sim.particles()[:, 0]
            rx = sim.tool_pose("roller")[0]
            if (direction > 0 and rx > xs.max() - 0.01) or (direction < 0 and rx < xs.min() + 0.01):
                break
            sim.step({"roller": np.array([0.4 * direction, 0.0, 0.0, 0.0])})
    sim.park_tool("roller")
    for _ in range(10):
        sim.step()
    helpers.snapshot(sim, "roll")
    p = sim.particles()
    h = np.percentile(p[:, 1], 95) - sim.floor_y
    foot = np.ptp(p[:, 0]) * np.ptp(p[:, 2])
    assert h < 0.6 * h0, (h0, h)
    assert foot > foot0
    assert sim.check() == 0


def test_pusher_moves_piece(fresh, helpers):
    sim = fresh
    length = 0.2
    sim.reset(helpers.dough(sim, seed=3, length=length, shift_x=-0.3), seed=0)
    c0 = sim.particles().mean(0)
    left = sim.particles()[:, 0].min()
    sim.set_tool_pose("pusher", (left - 0.015 - 0.005, sim.floor_y + 0.05 + 0.002, 0.5))
    for _ in range(10):  # 10 x 0.01 = 0.1 along +x
        sim.step({"pusher": np.array([1.0, 0.0, 0.0, 0.0])})
    sim.park_tool("pusher")
    for _ in range(10):
        sim.step()
    helpers.snapshot(sim, "push")
    c = sim.particles().mean(0)
    assert c[0] - c0[0] >= 0.07
    assert helpers.n_clusters(sim.observe().dough) == 1


def test_snapshot_restore_bitwise(fresh, helpers, tmp_path):
    sim = fresh
    sim.reset(helpers.dough(sim, seed=4), seed=5)
    sim.set_tool_pose("knife", (0.72, sim.floor_y + 0.19, 0.5))
    for _ in range(3):
        sim.step({"knife": [0.0, -1.0]})
    st = sim.get_state()
    rng = np.random.default_rng(0)
    acts = [{"knife": rng.uniform(-1, 1, 2), "pusher": rng.uniform(-1, 1, 4)} for _ in range(20)]
    for a in acts:
        sim.step(a)
    x1, o1 = sim.particles().copy(), sim.observe()
    sim.set_state(st)
    for a in acts:
        sim.step(a)
    x2, o2 = sim.particles(), sim.observe()
    assert np.array_equal(x1, x2)
    assert np.array_equal(o1.dough, o2.dough) and np.array_equal(o1.dough_index, o2.dough_index)
    for k in sim.tool_names:
        assert np.array_equal(o1.tool_poses[k], o2.tool_poses[k])
    # npz round trip, no pickle
    path = tmp_path / "state.npz"
    st.save(path)
    st2 = SimState.load(path)
    for k in ("x", "v", "F", "C", "tools", "obs_index"):
        assert np.array_equal(getattr(st, k), getattr(st2, k)), k
    assert st2.step == st.step == 3
    sim.set_state(st2)
    for a in acts:
        sim.step(a)
    assert np.array_equal(sim.particles(), x1)


def test_divergence_detected(fresh, helpers):
    sim = fresh
    sim.reset(helpers.dough(sim, seed=5), seed=0)
    sim.set_params(E=1e12, dt=1e-3)
    with pytest.raises(SimulationDiverged, match="env step"):
        for _ in range(5):
            sim.step()


def test_observation_and_tools(fresh, helpers):
    sim = fresh
    x = np.concatenate([box_particles((0.4, 0.06, 0.5), (0.1, 0.08, 0.07), 1500, 0),
                        sphere_particles((0.7, 0.06, 0.5), 0.04, 1000, 1)])
    obs = sim.reset(x, seed=3)
    assert obs.dough.shape == (1000, 3) and obs.dough.dtype == np.float32
    assert obs.dough_index.shape == (1000,)
    assert np.array_equal(obs.dough, sim.particles()[obs.dough_index])
    assert set(obs.tool_poses) == set(sim.tool_names) == set(obs.tool_points)
    for k in sim.tool_names:
        assert obs.tool_poses[k].shape == (7,)
        assert 50 <= obs.tool_points[k].shape[0] <= 200
        assert obs.tool_points[k][:, 1].min() > 0.5  # parked high up
    same = sim.reset(x, seed=3)
    assert np.array_equal(same.dough_index, obs.dough_index)
    sim.set_tool_pose("pusher", (0.5, 0.3, 0.5), yaw=0.3)
    pose = sim.observe().tool_poses["pusher"]
    assert np.allclose(pose[:3], (0.5, 0.3, 0.5)) and np.isclose(pose[3], np.cos(0.15), atol=1e-6)
    sim.step({"pusher": [1.0, 0.0, 0.0, 1.0]})
    pose = sim.observe().tool_poses["pusher"]
    assert np.isclose(pose[0], 0.51, atol=1e-6)
    # roller: rolling by angle a moves it a * r perpendicular to its axis, keeps y >= r
    sim.set_tool_pose("roller", (0.5, 0.0, 0.5))
    assert np.isclose(sim.tool_pose("roller")[1], 0.03)
    sim.step({"roller": [1.0, 0.0, 0.0, 0.0]})
    assert np.isclose(sim.tool_pose("roller")[0], 0.5 + 0.7 * 0.03, atol=1e-6)
    sim.park_tool("roller")
    assert sim.tool_pose("roller")[1] > 0.5


def test_bad_inputs(fresh, helpers):
    sim = fresh
    sim.reset(helpers.dough(sim), seed=0)
    with pytest.raises(ValueError, match="spoon"):
        sim.step({"spoon": [0.0, 0.0]})
    with pytest.raises(ValueError, match="knife"):
        sim.step({"knife": [0.0, 0.0, 0.0]})
    with pytest.raises(ValueError):
        sim.step({"pusher": [np.nan] * sim.tool_spec("pusher").action_dim})
    with pytest.raises(ValueError, match="yield_stres"):
        sim.set_params(yield_stres=3.0)
    with pytest.raises(ConfigError, match="nu"):
        SimConfig(nu=0.6)
    with pytest.raises(ConfigError, match="n_particles"):
        SimConfig(n_particles=0)
    with pytest.raises(ValueError):
        sim.reset(np.zeros((5, 2)))


def test_runtime_params_and_second_simulator(fresh, helpers):
    from pasta.sim import Simulator

    sim = fresh
    sim.reset(helpers.dough(sim), seed=0)
    sim.set_params(yield_stress=200.0, ground_friction=1.0, gravity=-100.0)
    sim.step()
    assert sim.params["yield_stress"] == 200.0
    # a second simulator with the same layout shares kernels; states do not mix
    other = Simulator(SimConfig(n_particles=3000, max_particles=10000), tools=get_plugins().simulated_tools(), seed=1)
    other.reset(box_particles((0.3, 0.06, 0.5), (0.1, 0.08, 0.08), 500, 0))
    x_main = sim.particles().copy()
    other.step()
    assert other.n_particles == 500
    assert np.array_equal(sim.particles(), x_main)
    sim.step()
    assert sim.n_particles == 3000


def test_render(fresh, helpers, tmp_path):
    sim = fresh
    obs = sim.reset(helpers.dough(sim), seed=0)
    out = render_png(tmp_path / "a.png", obs.dough, obs.tool_points, goal_points=obs.dough + 0.05, title="t")
    assert out.exists() and out.stat().st_size > 1000
