"""The example third-party package examples/pasta-pinch, installed as a distribution would be (a
*.dist-info with its entry point on sys.path, found by importlib.metadata like a pip install), taken
through what a plugin author does: list it, make demonstrations, train a feasibility predictor, plan with
its planner and execute its skill in the simulator."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from pasta.cli import main

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "pasta-pinch"
WEIGHTS = Path(__file__).resolve().parents[2] / "pasta" / "weights"


@pytest.fixture
def pinch_installed(install_example):
    """pasta-pinch 0.1.0 as an installed distribution (entry point ``pinch = pasta_pinch.plugin``)."""
    return install_example("pasta-pinch", "pasta-pinch", "pinch", "pasta_pinch")


def test_listed_with_its_tool_skill_and_planner(pinch_installed, capsys):
    plugins = pinch_installed
    assert not plugins.failures
    assert "pincer" in plugins.tools and "beam" in plugins.planners
    info = plugins.skills.info("pinch")
    assert (info.spec.n_in, info.spec.n_out, info.spec.tool, info.distribution) == (2, 1, "pincer", "pasta-pinch")
    assert main(["plugins"]) == 0
    out = capsys.readouterr().out
    assert "pinch" in out and "pincer" in out and "beam" in out


def test_contract_suites_pass_for_the_example(pinch_installed):
    """The example's own tests (examples/pasta-pinch/tests) are pasta's contract suites."""
    import pytest as _pytest

    assert _pytest.main([str(EXAMPLE / "tests"), "-q", "-p", "no:cacheprovider"]) == 0


@pytest.mark.sim
def test_demos_training_planning_and_execution(pinch_installed, tmp_path):
    from pasta.core.decompose import decompose
    from pasta.demos.scene import scene_particles
    from pasta.sim import SimConfig, Simulator
    from pasta.demos.data import load_demos
    from pasta.tasks.step import run_skill

    data, models, plan_dir = tmp_path / "demos", tmp_path / "models", tmp_path / "plan"
    # 2 demonstrations from the skill's own scene and expert
    assert main(["demos", "skill=pinch", "num=2", f"out={data}", "workers=0", "n_particles=3000", "obs_points=600"]) == 0
    demos = list(load_demos(data, ["pinch"]))
    assert len(demos) == 2
    for demo in demos:
        assert demo.action.shape[1] == 5  # the pincer's x, y, z, yaw, open
        assert len(decompose(demo.dough[0], num_points=128)) == 2 and len(decompose(demo.after, num_points=128)) == 1

    # 1 epoch of feasibility training on the shipped VAE, into a models root that also has the shipped cost
    for part in ("vae", "cost"):
        shutil.copytree(WEIGHTS / part, models / part)
    assert main(["train", "feasibility", f"data={data}", f"out={models}", "skill=pinch", "epochs=1", "hidden=32",
                 "num_points=256", "match_points=64", "hard_per_positive=2"]) == 0
    metrics = json.loads((models / "feasibility" / "pinch" / "metrics.json").read_text())
    assert metrics["train_positives"] > 0

    # plan from the first demonstration's clouds with the example's planner and skill only; the 1-epoch
    # feasibility network predicts ~0.48, so the bar of the unreachable flag (exit code 3) is lowered
    demo = demos[0]
    np.save(tmp_path / "obs.npy", demo.dough[0])
    np.save(tmp_path / "goal.npy", demo.after)
    assert main(["plan", f"obs={tmp_path / 'obs.npy'}", f"goal={tmp_path / 'goal.npy'}", f"out={plan_dir}",
                 f"models={models}", "skills=pinch", "horizon=1", "planner=beam", "planner.num_samples=32",
                 "planner.probe_samples=8", "planner.iterations=10", "seed=0", "check.min_feasibility=0"]) == 0
    plan = json.loads((plan_dir / "plan.json").read_text())
    assert plan["skills"] == ["pinch"] and plan["planner"] == "beam" and plan["steps"][0]["inputs"] == [0, 1]
    subgoal = np.load(plan_dir / "step_0_subgoal.npy")
    assert subgoal.shape[0] == 1 and np.isfinite(subgoal).all()

    # execute the planned step with the skill's heuristic controller in the simulator: two pieces -> one
    skill = pinch_installed.skills.create("pinch")
    sim = Simulator(SimConfig(n_particles=3000, obs_points=600), tools=pinch_installed.simulated_tools())
    rng = np.random.default_rng(0)
    sim.reset(scene_particles(skill.demo_scene(rng, sim.floor_y), 3000, rng)[0], seed=0)
    for _ in range(5):
        sim.step()
    obs = sim.observe()
    assert len(decompose(obs.dough, num_points=128)) == 2
    run = run_skill(sim, skill, skill.controller(), np.arange(len(obs.dough)), subgoal[0])
    after = sim.observe().dough
    assert run.steps > 0 and len(decompose(after, num_points=128)) == 1
    assert np.ptp(after[:, 0]) < np.ptp(obs.dough[:, 0]) - 0.02  # the fingers pressed the pieces together
