"""The forward kernel against golden checksums, and run-to-run determinism.

The digests are of the particle state (x, v, F, C as float32 bytes) after short knife, pusher and roller
sequences, yawed tools included, and on a dough of 2,999 particles (not a multiple of the 4 whose SVDs run side by
side). They were written by the kernel of 2026-12-05 (frozen as benchmarks/engine_v1.py for the speed comparison)
and the faster kernel reproduces them bit for bit. A kernel change that moves any float bit fails here: when that is
intended, regenerate them (``python tests/sim/test_kernel_golden.py`` prints the current ones), and with them the
tasks' instance checksums (``GENERATOR_VERSION``) and the results table (docs/simulator.md, "Golden checksums").
"""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

from pasta.sim import SimConfig, Simulator, crs_dough

pytestmark = pytest.mark.sim

GOLDEN = {
    "knife_pusher": "a51b215200a927ab",
    "roller": "f0a3169029b5b67d",
    "yawed_knife": "1c9678a02a25803e",
    "yawed_roller": "a8324b3e7494b24a",
    "odd_count": "5faacf502abd720c",
}


def three_tool_sim() -> Simulator:
    """Knife, pusher and roller in that order (tools act on a grid node in the simulator's order)."""
    from pasta.plugins import get_plugins

    reg = get_plugins().tools
    return Simulator(SimConfig(n_particles=3000, max_particles=10000),
                     tools=[reg.info(n).spec for n in ("knife", "pusher", "roller")])


def _sequence(fy: float) -> list:
    """A short knife + pusher episode: ("pose", tool, position, yaw) / ("park", tool) / actions."""
    seq: list = [("pose", "knife", (0.72, fy + 0.19, 0.5), 0.0)]
    seq += [{"knife": [0.0, -1.0]}] * 8 + [{"knife": [-0.5, 0.0]}] * 4 + [{"knife": [0.0, 1.0]}] * 4
    seq += [("park", "knife"), ("pose", "pusher", (0.55, fy + 0.052, 0.5), 0.2)]
    seq += [{"pusher": [1.0, 0.0, 0.0, 0.3]}] * 5 + [{"pusher": [0.0, 0.5, -0.5, -1.0]}] * 2
    seq += [("park", "pusher"), {}]
    return seq


def _roll_sequence(fy: float) -> list:
    seq: list = [("pose", "roller", (0.7, fy + 0.09, 0.5), 0.0)]
    seq += [{"roller": [0.5, 0.0, -1.0, 0.3]}] * 4 + [{"roller": [-0.5, 0.0, 0.0]}] * 3 + [{}] * 2
    return seq


def _yawed(tool: str, fy: float) -> list:
    y, action = {"knife": (0.15, [0.0, -1.0]), "roller": (0.09, [0.0, 0.0, -1.0, 0.0])}[tool]
    return [("pose", tool, (0.7, fy + y, 0.5), 0.1)] + [{tool: action}] * 2


def _run(sim: Simulator, seq: list) -> None:
    for item in seq:
        if isinstance(item, dict):
            sim.step(item)
        elif item[0] == "pose":
            sim.set_tool_pose(item[1], item[2], yaw=item[3])
        else:
            sim.park_tool(item[1])


def _reset(sim: Simulator, seed: int, n: int = 3000) -> None:
    sim.reset(crs_dough(n, np.random.default_rng(seed), floor_y=sim.floor_y, length=0.3, depth=0.07), seed=0)


def digest(sim: Simulator) -> str:
    st = sim.get_state()
    h = hashlib.sha256()
    for name in ("x", "v", "F", "C"):
        h.update(np.ascontiguousarray(getattr(st, name), dtype=np.float32).tobytes())
    return h.hexdigest()[:16]


def digests(sim: Simulator) -> dict[str, str]:
    """The state digest after each golden scene (one simulator, scenes in a fixed order)."""
    fy = sim.floor_y
    out = {}
    _reset(sim, 0)
    _run(sim, _sequence(fy))
    out["knife_pusher"] = digest(sim)
    _run(sim, _roll_sequence(fy))
    out["roller"] = digest(sim)
    for tool in ("knife", "roller"):
        _reset(sim, 1)
        _run(sim, _yawed(tool, fy))
        out[f"yawed_{tool}"] = digest(sim)
    _reset(sim, 2, n=2999)  # not a multiple of the 4 particles whose SVDs run side by side
    _run(sim, _sequence(fy)[:10])
    out["odd_count"] = digest(sim)
    return out


@pytest.fixture(scope="module")
def sim():
    return three_tool_sim()


def test_kernel_reproduces_golden_checksums(sim):
    got = digests(sim)
    assert got == GOLDEN, {k: (got[k], GOLDEN[k]) for k in GOLDEN if got[k] != GOLDEN[k]}


def test_deterministic_run_to_run(sim):
    outs = []
    for _ in range(2):
        _reset(sim, 0)
        _run(sim, _sequence(sim.floor_y) + _roll_sequence(sim.floor_y))
        outs.append(sim.get_state())
    for name in ("x", "v", "F", "C", "tools"):
        assert np.array_equal(getattr(outs[0], name), getattr(outs[1], name)), name


if __name__ == "__main__":
    print(digests(three_tool_sim()))
