"""Tools as plugin data: ToolSpec validation, registered tools, a gripper, a static obstacle, old states."""

from __future__ import annotations

import numpy as np
import pytest

from pasta.core.errors import ConfigError, InputError, PluginValidationError
from pasta.core.tool import ActionChannel, Box, Capsule, FingerPair, ToolSpec, WedgeBlade
from pasta.plugins import get_plugins
from pasta.sim import SimConfig, SimState, Simulator, ToolTable, box_particles

GRIPPER = ToolSpec(
    "test_gripper",
    description="two-finger parallel gripper (test)",
    primitives=(FingerPair(half=(0.01, 0.04, 0.04), aperture=0.14, min_aperture=0.0, max_aperture=0.2),),
    action=(ActionChannel("x", 0.01), ActionChannel("y", 0.01), ActionChannel("z", 0.01), ActionChannel("open", 0.01)),
    park=(0.5, 0.8, 0.85),
    friction=5.0,
)
BOARD = ToolSpec("test_board", description="a raised board (static obstacle)",
                 primitives=(Box(half=(0.1, 0.02, 0.1)),), park=(0.5, 0.5, 0.85))


def test_toolspec_validation_names_tool_and_field():
    with pytest.raises(PluginValidationError, match=r"tool 'bad'.*half"):
        ToolSpec("bad", primitives=(Box(half=(0.1, -1.0, 0.1)),), park=(0.5, 0.5, 0.5))
    with pytest.raises(PluginValidationError, match=r"tool 'bad'.*park"):
        ToolSpec("bad", primitives=(Box(half=(0.1, 0.1, 0.1)),))
    with pytest.raises(PluginValidationError, match=r"tool 'bad'.*'spin'"):
        ToolSpec("bad", primitives=(Box(half=(0.1, 0.1, 0.1)),), action=(ActionChannel("spin", 1.0),), park=(0.5, 0.5, 0.5))
    with pytest.raises(PluginValidationError, match=r"tool 'bad'.*roll"):
        ToolSpec("bad", primitives=(Box(half=(0.1, 0.1, 0.1)),), action=(ActionChannel("roll", 1.0),), park=(0.5, 0.5, 0.5))
    with pytest.raises(PluginValidationError, match=r"tool 'bad'.*open.*finger_pair"):
        ToolSpec("bad", primitives=(Box(half=(0.1, 0.1, 0.1)),), action=(ActionChannel("open", 1.0),), park=(0.5, 0.5, 0.5))
    with pytest.raises(PluginValidationError, match=r"tool 'bad'.*required_action"):
        ToolSpec("bad", primitives=(Box(half=(0.1, 0.1, 0.1)),), action=(ActionChannel("x", 1.0),), required_action=2,
                 park=(0.5, 0.5, 0.5))
    with pytest.raises(PluginValidationError, match=r"tool 'bad'.*scale"):
        ToolSpec("bad", primitives=(Box(half=(0.1, 0.1, 0.1)),), action=(ActionChannel("x", 0.0),), park=(0.5, 0.5, 0.5))
    with pytest.raises(PluginValidationError, match=r"tool 'bad'.*aperture"):
        ToolSpec("bad", primitives=(FingerPair(half=(0.01, 0.01, 0.01), aperture=0.3, max_aperture=0.2),), park=(0.5, 0.5, 0.5))
    with pytest.raises(PluginValidationError, match=r"tool 'bad'.*at most"):
        ToolSpec("bad", primitives=(Box(half=(0.1, 0.1, 0.1)),) * 5, park=(0.5, 0.5, 0.5))
    with pytest.raises(PluginValidationError, match=r"tool 'bad'.*surface_points"):
        ToolSpec("bad", primitives=(Box(half=(0.1, 0.1, 0.1)),), park=(0.5, 0.5, 0.5), surface_points=((0.0, 1.0),))
    # derived facts
    knife_like = ToolSpec("k", primitives=(WedgeBlade(half=(0.025, 0.1, 0.06)),), park=(0.1, 0.8, 0.1))
    assert knife_like.lowest_centre == pytest.approx(0.1) and knife_like.is_static
    cap = ToolSpec("c", primitives=(Capsule(radius=0.03, half_length=0.075),), action=(ActionChannel("roll", 0.7),),
                   park=(0.1, 0.8, 0.1))
    assert cap.roll_radius == 0.03 and cap.bound_radius == pytest.approx(0.105)
    assert [s[0] for s in GRIPPER.draw()] == ["cube", "cube"]
    assert ToolSpec("name_only").simulated is False  # analytic plugins: a name, nothing simulated


def test_stand_pose_is_checked_and_left_out_of_the_repr():
    board = ToolSpec("b", primitives=(Box(half=(0.15, 0.025, 0.16)),), park=(0.3, 0.9, 0.5), stand=(0.3, 0.045, 0.5))
    assert board.stand == (0.3, 0.045, 0.5) and board.stand_top == pytest.approx(0.07)
    # task cache keys hash the repr of the tools: declaring a stand pose must not change them
    assert "stand" not in repr(board)
    assert repr(board) == repr(ToolSpec("b", primitives=(Box(half=(0.15, 0.025, 0.16)),), park=(0.3, 0.9, 0.5)))
    with pytest.raises(PluginValidationError, match="tool 'b': stand .* inside the unit-cube"):
        ToolSpec("b", primitives=(Box(half=(0.1, 0.1, 0.1)),), park=(0.5, 0.5, 0.5), stand=(0.3, 1.5, 0.5))
    with pytest.raises(PluginValidationError, match="name-only tool.*stand"):
        ToolSpec("b", stand=(0.3, 0.1, 0.5))
    with pytest.raises(PluginValidationError, match="tool 'k' has no stand pose"):
        ToolSpec("k", primitives=(Box(half=(0.1, 0.1, 0.1)),), park=(0.5, 0.5, 0.5)).stand_top


def test_builtin_tools_are_registered_with_their_skills():
    tools = {t.name: t for t in get_plugins().simulated_tools()}
    assert {"knife", "pusher", "roller"} <= set(tools)
    for info in get_plugins().skills:
        assert info.spec.tool in tools
    assert tools["roller"].required_action == 3 and tools["roller"].action_dim == 4


def test_tool_table_limits():
    with pytest.raises(ConfigError, match="at most 8"):
        ToolTable([ToolSpec(f"t{i}", primitives=(Box(half=(0.01, 0.01, 0.01)),), park=(0.5, 0.8, 0.5)) for i in range(9)], {}, 1 / 64)
    with pytest.raises(ConfigError, match="no geometry"):
        ToolTable([ToolSpec("name_only")], {}, 1 / 64)
    with pytest.raises(ConfigError, match="unknown tools"):
        ToolTable([BOARD], {"knife": 1.0}, 1 / 64)
    t = ToolTable([GRIPPER], {}, 1 / 64)
    pts = t.surface_points("test_gripper", np.array([0.5, 0.5, 0.5, 0.0, 0.0, 0.1]))
    assert pts.shape == (100, 3)
    assert np.isclose(np.abs(pts[:, 0] - 0.5).max(), 0.05 + 0.02)  # outer faces at aperture / 2 + 2 half widths


@pytest.fixture(scope="module")
def toolsim(sim):
    """A simulator with the built-in tools plus a test gripper and board (same layout: no new kernels).

    Built-in only: with a third-party tool installed (the example pasta-pinch's pincer), all registered tools
    plus these two would exceed the simulator's tool slots."""
    from pasta.plugins.registry import BUILTIN_DISTRIBUTION

    reg = get_plugins().tools
    builtin = [t for t in get_plugins().simulated_tools() if reg.info(t.name).distribution == BUILTIN_DISTRIBUTION]
    other = Simulator(SimConfig(n_particles=3000, max_particles=10000), tools=[*builtin, GRIPPER, BOARD])
    assert other._eng is sim._eng  # tools are field data: one compiled engine serves every tool set
    return other


@pytest.mark.sim
def test_gripper_squeezes_dough(toolsim):
    sim = toolsim
    fy = sim.floor_y
    sim.reset(box_particles((0.5, fy + 0.03, 0.5), (0.1, 0.06, 0.06), 2000, 0), seed=0)
    sim.set_tool_pose("test_gripper", (0.5, 0.0, 0.5))  # clamped: finger bottoms at y = 0
    assert np.isclose(sim.tool_pose("test_gripper")[1], 0.04)
    assert sim.tool_aperture("test_gripper") == pytest.approx(0.14)
    width0 = np.ptp(np.percentile(sim.particles()[:, 0], [1, 99]))
    for _ in range(6):  # 0.14 -> 0.08
        sim.step({"test_gripper": [0.0, 0.0, 0.0, -1.0]})
    assert sim.tool_aperture("test_gripper") == pytest.approx(0.08)
    for _ in range(3):
        sim.step()
    x = sim.particles()
    width = np.ptp(np.percentile(x[:, 0], [1, 99]))
    assert width < width0 - 0.012, (width0, width)
    assert sim.check() == 0
    assert abs(x[:, 0].mean() - 0.5) < 0.01  # squeezed from both sides
    # the surface points follow the aperture
    pts = sim.observe().tool_points["test_gripper"]
    assert np.isclose(np.abs(pts[:, 0] - 0.5).min(), 0.04, atol=1e-6)
    with pytest.raises(InputError, match="test_gripper"):
        sim.step({"test_gripper": [0.0, 0.0]})


@pytest.mark.sim
def test_static_board_supports_dough(toolsim):
    sim = toolsim
    with pytest.raises(InputError, match="static"):
        sim.reset(box_particles((0.5, 0.2, 0.5), (0.06, 0.06, 0.06), 500, 0))
        sim.step({"test_board": []})
    results = {}
    for placed in (True, False):
        sim.reset(box_particles((0.5, 0.155, 0.5), (0.06, 0.06, 0.06), 1500, 1), seed=0)
        if placed:
            sim.set_tool_pose("test_board", (0.5, 0.1, 0.5))  # top face at y = 0.12
        for _ in range(40):
            sim.step()
        results[placed] = sim.particles()[:, 1]
    assert np.percentile(results[True], 1) > 0.11  # resting on the board
    assert results[False].min() < 0.05  # without it the same dough falls to the floor


@pytest.mark.sim
def test_tool_friction_override_and_set_params(toolsim):
    sim = toolsim
    assert sim.tool_friction["pusher"] == 5.0 and sim.tool_friction["test_gripper"] == 5.0
    other = Simulator(SimConfig(n_particles=3000, max_particles=10000, tool_friction={"pusher": 1.5}),
                      tools=get_plugins().simulated_tools())
    assert other.tool_friction["pusher"] == 1.5
    other.set_params(knife_friction=0.25)
    assert other.tool_friction["knife"] == 0.25
    with pytest.raises(ValueError, match="spoon_friction"):
        other.set_params(spoon_friction=1.0)
    with pytest.raises(ConfigError, match="spoon"):
        Simulator(SimConfig(tool_friction={"spoon": 1.0}), tools=get_plugins().simulated_tools())


@pytest.mark.sim
def test_states_round_trip_and_an_older_format_is_refused(toolsim, tmp_path):
    sim = toolsim
    x = box_particles((0.5, 0.06, 0.5), (0.1, 0.08, 0.07), 300, 0)
    sim.reset(x, seed=0)
    back = sim.get_state()
    assert back.tools.shape == (len(sim.tool_names), 6) and back.tool_names == sim.tool_names
    back.save(tmp_path / "new.npz")
    again = SimState.load(tmp_path / "new.npz")
    assert np.array_equal(again.tools, back.tools) and again.tool_names == back.tool_names
    # a state saved before tools were plugins: three unnamed tools, five columns (no aperture)
    n = len(x)
    old = dict(x=x, v=np.zeros((n, 3), np.float32), F=np.tile(np.eye(3, dtype=np.float32), (n, 1, 1)),
               C=np.zeros((n, 3, 3), np.float32), tools=np.zeros((3, 5)), obs_index=np.arange(0, n, 3), step=np.int64(7))
    np.savez(tmp_path / "old.npz", **old)
    with pytest.raises(InputError, match=r"older format \(tools \(3, 5\), no tool names"):
        SimState.load(tmp_path / "old.npz")
    # rows without names are in the simulator's order; the count must match
    with pytest.raises(InputError, match="state.tools"):
        sim.set_state(SimState(back.x, back.v, back.F, back.C, back.tools[:2], back.obs_index))


def test_tool_shapes_for_viewers():
    from pasta.sim.tools import tool_quat, tool_shapes
    from pasta_skill_roll.tool import ROLLER

    pose = np.concatenate([[0.5, 0.3, 0.5], tool_quat(np.pi / 2, 0.0)])
    (a, b) = tool_shapes(GRIPPER, pose, aperture=0.1)
    assert (a[0], b[0], a[1]) == ("test_gripper.0", "test_gripper.1", "cube")
    assert np.allclose(a[2], (0.02, 0.08, 0.08))
    # yaw 90 degrees turns local x into world -z: the fingers sit at z = 0.5 +- (0.05 + 0.01)
    assert np.allclose(sorted([a[3][2], b[3][2]]), (0.44, 0.56)) and np.allclose(a[3][[0, 1]], (0.5, 0.3))
    ((name, kind, size, centre, quat),) = tool_shapes(ROLLER, np.array([0.4, 0.1, 0.5, 1.0, 0.0, 0.0, 0.0]))
    assert (name, kind) == ("roller", "cylinder") and np.allclose(size, (0.06, 0.06, 0.15)) and np.allclose(centre, (0.4, 0.1, 0.5))


def test_simconfig_refuses_older_run_configs_and_reads_omegaconf():
    from dataclasses import asdict

    from omegaconf import OmegaConf

    now = asdict(SimConfig(tool_friction={"knife": 0.1}))
    assert SimConfig.from_dict(now) == SimConfig(tool_friction={"knife": 0.1})
    old = {k: v for k, v in now.items() if k not in ("tool_friction", "fast_math")}
    old.update(knife_friction=0.0, pusher_friction=5.0)  # a sim_config.json of older runs
    with pytest.raises(ConfigError, match="older format .knife_friction, pusher_friction, no fast_math"):
        SimConfig.from_dict(old)
    with pytest.raises(ConfigError, match="unknown simulator settings"):
        SimConfig.from_dict({**now, "n_gird": 3})
    conf = OmegaConf.merge(OmegaConf.structured(SimConfig), OmegaConf.from_dotlist(["tool_friction.knife=0.3"]))
    assert OmegaConf.to_object(conf).tool_friction == {"knife": 0.3}
    with pytest.raises(ConfigError, match="tool_friction.knife"):
        SimConfig(tool_friction={"knife": -1.0})
