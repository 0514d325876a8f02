"""The example third-party package examples/pasta-press, installed as a distribution would be: a skill with no
scripted expert and no heuristic controller, taught by trajectory optimisation. Taken through what its author
does: list it, run pasta's contract suite, make a demonstration by GBTO, train on it, and run the shipped learned
policy (examples/pasta-press/press_weights) in the simulator."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from pasta.cli import main

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "pasta-press"


@pytest.fixture
def press_installed(install_example):
    """pasta-press 0.1.0 as an installed distribution (entry point ``press = pasta_press.plugin``)."""
    return install_example("pasta-press", "pasta-press", "press", "pasta_press")


def test_listed_as_a_skill_that_makes_demonstrations_by_optimisation(press_installed, capsys):
    from pasta.demos import demo_skills

    plugins = press_installed
    assert not plugins.failures
    cls = type(plugins.skills.create("press"))
    assert cls.has_gbto() and not cls.has_expert() and "press" in demo_skills()
    assert main(["plugins"]) == 0
    out = capsys.readouterr().out
    assert "press" in out and "plate" in out


def test_contract_suite_passes_for_the_example(press_installed):
    import pytest as _pytest

    assert _pytest.main([str(EXAMPLE / "tests"), "-q", "-p", "no:cacheprovider"]) == 0


@pytest.mark.sim
def test_demonstration_by_optimisation_training_and_the_learned_press(press_installed, tmp_path):
    from pasta.demos.data import load_demos
    from pasta.demos.scene import scene_particles
    from pasta.policy.learned import load_policy
    from pasta.sim import SimConfig, Simulator
    from pasta.tasks.step import run_skill

    data, models = tmp_path / "demos", tmp_path / "models"
    # one demonstration by GBTO at the skill's own budget (12 iterations of 24 steps, its training_defaults), on
    # fewer particles
    assert main(["demos", "skill=press", "num=1", f"out={data}", "workers=0", "n_particles=1500", "obs_points=300"]) == 0
    (demo,) = load_demos(data, ["press"])
    assert demo.params["expert"] == "trajopt" and len(demo.params["losses"]) == 12
    assert demo.action.shape == (24, 1)  # the plate's one channel: y
    best = demo.params["best_iteration"]
    assert demo.params["losses"][best] < demo.params["losses"][0]
    assert (demo.action < 0).all()  # the optimiser found that the plate must come down
    height = lambda cloud: float(np.ptp(cloud[:, 1]))  # noqa: E731
    assert height(demo.after) < height(demo.dough[0]) - 0.005  # and it pressed the piece

    # the demonstration trains a policy like an expert's would (one short epoch)
    assert main(["train", "policy", f"data={data}", f"out={models}", "skill=press", "epochs=1", "steps_per_epoch=2",
                 "dough_points=128", "goal_points=128"]) == 0
    assert json.loads((models / "policy" / "press" / "metrics.json").read_text())

    # planning with the shipped press networks (beside pasta's VAE and cost): from the demonstration's block to a
    # flattened one
    plugins = press_installed
    skill = plugins.skills.create("press")
    obs, goal, plan_dir = tmp_path / "obs.npy", tmp_path / "goal.npy", tmp_path / "plan"
    np.save(obs, demo.dough[0])
    np.save(goal, skill.demo_target(demo.dough[0], np.random.default_rng(0)))
    assert main(["plan", f"obs={obs}", f"goal={goal}", f"out={plan_dir}", f"models={EXAMPLE / 'press_weights'}",
                 "skills=press", "horizon=1", "seed=0"]) == 0
    plan = json.loads((plan_dir / "plan.json").read_text())
    assert plan["skills"] == ["press"] and plan["steps"][0]["inputs"] == [0]

    # the shipped policy, trained on such demonstrations, presses a held-out block toward a drawn target
    load_policy(EXAMPLE / "press_weights" / "policy" / "press", skill)
    sim = Simulator(SimConfig(n_particles=1500, obs_points=300), tools=plugins.simulated_tools())
    rng = np.random.default_rng(123)
    sim.reset(scene_particles(skill.demo_scene(rng, sim.floor_y), 1500, rng)[0], seed=0)
    for _ in range(10):
        sim.step()
    before = sim.observe().dough
    target = skill.demo_target(before, rng)
    run = run_skill(sim, skill, skill.policy(), np.arange(len(before)), target)
    after = sim.observe().dough
    assert run.steps > 0
    assert abs(height(after) - height(target)) < 0.5 * abs(height(before) - height(target))
