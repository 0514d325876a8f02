"""Run logs draw every tool in its ToolSpec colour (Foxglove SceneUpdate), grey when the spec names none."""

import numpy as np
from matplotlib.colors import to_rgba

from pasta.execute.runlog import ExecutionLog as _Log, _tool_rgba
from pasta.io import RunLogger, RunReader
from pasta.io.schemas import DEFAULT_TOOL_COLOR
from pasta.plugins import get_plugins


class _ToolsOnlySim:
    """The part of the simulator `_Log.tools` reads: registered tools at fixed poses."""

    class cfg:
        dt, substeps = 1e-4, 20

    def __init__(self, names):
        self.tool_names = tuple(names)
        self.step_count = 0

    def tool_spec(self, name):
        return get_plugins().tools.spec(name)

    def tool_pose(self, name):
        return np.array([0.5, 0.2, 0.5, 1.0, 0.0, 0.0, 0.0], np.float32)

    def tool_aperture(self, name):
        return 0.05


def test_named_colour_becomes_rgba_and_empty_is_the_default():
    assert _tool_rgba("tab:brown") == to_rgba("tab:brown")
    assert _tool_rgba("") == tuple(DEFAULT_TOOL_COLOR)


def test_logged_tools_carry_their_spec_colour(tmp_path):
    names = ["spatula", "gripper", "board", "knife"]
    sim = _ToolsOnlySim(names)
    path = tmp_path / "tools.mcap"
    with RunLogger(path) as logger:
        _Log(logger, sim).tools(0)
    [(_, prims)] = list(RunReader(path).messages("/tools"))
    colour = {p.name.split(".")[0]: tuple(round(c, 4) for c in p.color) for p in prims}
    for name in names:
        expected = tuple(round(c, 4) for c in _tool_rgba(sim.tool_spec(name).color))
        assert colour[name] == expected, name
    # the gripper's two fingers are two primitives, both in the gripper's colour
    assert sum(p.name.startswith("gripper") for p in prims) == 2
    assert colour["spatula"] != colour["knife"]
