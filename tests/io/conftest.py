import numpy as np
import pytest

DT = 2e-3


def make_run(path, seed=0, n_steps=12, chunk_size=1024 * 1024, n_points=300):
    """Write a representative run; returns what was written, per topic, for comparisons."""
    from pasta.io import RunLogger, ToolPrimitive, step_time_ns

    rng = np.random.default_rng(seed)
    written = {"/dough": [], "/tools": [], "/actions": [], "/entities": [], "/plan": [],
               "/metrics": [], "/step": [], "/log": [], "/planner/progress": [], "/custom": [],
               "/goal": [], "/colored": []}
    config = "seed: 3\nplanner:\n  name: exhaustive\n  horizon: 3\n"
    meta = {"seed": "3", "pasta": "0.1.0", "plugins.cut": "0.1.0"}
    with RunLogger(path, config_yaml=config, metadata=meta, chunk_size=chunk_size) as log:
        goal = rng.random((n_points, 3)).astype(np.float32)
        log.point_cloud("/goal", 0, goal)
        written["/goal"].append((0, goal))
        ents = [rng.random((40, 3)).astype(np.float32), rng.random((25, 3)).astype(np.float32)]
        log.entities("/entities", 0, ents)
        written["/entities"].append((0, ents))
        plan = {"skills": ["cut", "push", "roll"], "steps": [{"skill": "cut", "inputs": [0], "outputs": 2}], "score": 0.75}
        log.plan(0, plan)
        written["/plan"].append((0, plan))
        for i in range(5):
            prog = {"iteration": i, "best_score": 0.1 * i, "sequence": ["cut", "push"]}
            log.planner_progress(i, prog)
            written["/planner/progress"].append((i, prog))
        log.set_tool_pose(0, 0, "knife", [0.5, 0.2, 0.5], yaw=0.25)
        written["/actions"].append((0, {"step": 0, "set_tool_pose": {"name": "knife", "position": [0.5, 0.2, 0.5], "yaw": 0.25}}))
        x = rng.random((n_points, 3)).astype(np.float32)
        for i in range(n_steps):
            t = step_time_ns(i, DT)
            x = x + rng.normal(0, 1e-3, x.shape).astype(np.float32)
            log.point_cloud("/dough", t, x)
            written["/dough"].append((t, x.copy()))
            cols = rng.integers(0, 256, (50, 4), dtype=np.uint8)
            cpts = rng.random((50, 3)).astype(np.float32)
            log.point_cloud("/colored", t, cpts, cols)
            written["/colored"].append((t, cpts, cols))
            tools = [
                ToolPrimitive("knife", "cube", (0.005, 0.1, 0.08), (0.5, 0.2 - 0.01 * i, 0.5), (0.99, 0.0, 0.1, 0.0)),
                ToolPrimitive("roller", "cylinder", (0.04, 0.04, 0.2), (0.3, 0.1, 0.3), (0.7071, 0.7071, 0.0, 0.0), (1.0, 0.0, 0.0, 1.0)),
            ]
            log.tools("/tools", t, tools)
            written["/tools"].append((t, tools))
            act = [0.0, -0.01, 0.0]
            log.action(t, i, "knife", np.array(act))
            written["/actions"].append((t, {"step": i, "tool": "knife", "action": act}))
            if i % 4 == 0:
                log.message(t, "info", f"env step {i}")
                written["/log"].append((t, ("info", f"env step {i}")))
        log.park_tool(step_time_ns(n_steps, DT), n_steps, "knife")
        written["/actions"].append((step_time_ns(n_steps, DT), {"step": n_steps, "park_tool": "knife"}))
        log.message(step_time_ns(n_steps, DT), "warning", "knife stopped early")
        written["/log"].append((step_time_ns(n_steps, DT), ("warning", "knife stopped early")))
        step = {"step": 0, "skill": "cut", "score": 0.5}
        log.step_result(step_time_ns(n_steps, DT), step)
        written["/step"].append((step_time_ns(n_steps, DT), step))
        metrics = {"normalized_improvement": 0.81, "success": True, "emd": 0.0123}
        log.metrics(step_time_ns(n_steps, DT), metrics)
        written["/metrics"].append((step_time_ns(n_steps, DT), metrics))
        custom = {"nested": {"a": [1, 2, 3]}, "name": "x"}
        log.json("/custom", 7, custom)
        written["/custom"].append((7, custom))
        log.attach("initial_state.npz", b"\x93NUMPY-ish bytes \x00\xff" * 10, "application/x-npz")
    return {"written": written, "config": config, "metadata": meta,
            "attachments": {"config.yaml": config.encode(), "initial_state.npz": b"\x93NUMPY-ish bytes \x00\xff" * 10}}


@pytest.fixture
def sample_run(tmp_path):
    path = tmp_path / "run.mcap"
    info = make_run(path)
    info["path"] = path
    return info


@pytest.fixture
def run_factory():
    """``run_factory(path, seed=0, n_steps=12, chunk_size=...)`` writes a sample run."""
    return make_run
