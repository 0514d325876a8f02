"""Acceptance 2: `pasta replay --verify` reproduces a logged single-skill episode (real simulator)."""

import argparse
import io
from dataclasses import asdict

import numpy as np
import pytest

from pasta.io import RunLogger, RunReader, ToolPrimitive, step_time_ns
from pasta.io import replay
from pasta.plugins import get_plugins

pytestmark = pytest.mark.sim


def _state_bytes(state):
    buf = io.BytesIO()
    state.save(buf)
    return buf.getvalue()


def _knife_episode(path, n_steps=7, final_attachment=True):
    from pasta.sim import SimConfig, Simulator, crs_dough

    cfg = SimConfig(n_grid=32, max_particles=1500, n_particles=1500, obs_points=300, seed=7)
    sim = Simulator(cfg, tools=get_plugins().simulated_tools())
    sim.reset(crs_dough(cfg.n_particles, rng=7, floor_y=sim.floor_y))
    env_dt = cfg.dt * cfg.substeps
    with RunLogger(path, metadata={"seed": str(cfg.seed), "skill": "cut"}) as log:
        log.attach("initial_state.npz", _state_bytes(sim.get_state()), "application/x-npz")
        log.attach_json("sim_config.json", asdict(cfg))
        x_cut = float(sim.particles()[:, 0].mean())
        sim.set_tool_pose("knife", [x_cut, 0.21, 0.5], yaw=0.0)
        log.set_tool_pose(0, 0, "knife", [x_cut, 0.21, 0.5], yaw=0.0)
        for i in range(n_steps):
            t = step_time_ns(i + 1, env_dt)
            action = np.array([0.0, -1.0], dtype=np.float32)
            sim.step({"knife": action})
            log.action(t, i, "knife", action)
            pose = sim.tool_pose("knife")
            log.tools("/tools", t, [ToolPrimitive("knife", "cube", (0.05, 0.2, 0.12), pose[:3], pose[3:])])
            log.point_cloud("/dough", t, sim.observe().dough)
        sim.park_tool("knife")
        log.park_tool(step_time_ns(n_steps + 1, env_dt), n_steps, "knife")
        final = sim.get_state()
        if final_attachment:
            log.attach("final_state.npz", _state_bytes(final), "application/x-npz")
    return final


def _run(argv):
    parser = argparse.ArgumentParser()
    replay.add_arguments(parser)
    return replay.run(parser.parse_args(argv))


def test_replay_verify_reproduces_knife_episode(tmp_path, capsys):
    path = tmp_path / "cut.mcap"
    final = _knife_episode(path)
    x0 = RunReader(path).attachment("initial_state.npz")
    from pasta.sim import SimState

    moved = np.abs(final.x - SimState.load(io.BytesIO(x0)).x).max()
    assert moved > 1e-4  # the knife really deformed the dough
    assert _run([str(path), "tolerance=1e-5", "--verify"]) == 0
    out = capsys.readouterr().out
    assert "7 env steps re-simulated" in out and "OK" in out

    # a tampered final state is caught
    r = RunReader(path)
    bad = tmp_path / "bad.mcap"
    with RunLogger(bad) as log:
        for name in ("initial_state.npz", "sim_config.json"):
            log.attach(name, r.attachment(name))
        for t, msg in r.messages("/actions"):
            log.json("/actions", t, msg)
        final.x[0, 1] += 1e-3
        log.attach("final_state.npz", _state_bytes(final))
    assert _run([str(bad), "--verify"]) == replay.EXIT_VERIFY_FAILED
    assert "FAILED" in capsys.readouterr().out


def test_replay_verify_against_last_observation(tmp_path, capsys):
    path = tmp_path / "cut_obs.mcap"
    _knife_episode(path, n_steps=3, final_attachment=False)
    assert _run([str(path), "--verify"]) == 0
    assert "last /dough" in capsys.readouterr().out
