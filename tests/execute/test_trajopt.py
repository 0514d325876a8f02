"""The Traj-Opt baseline (`method=trajopt`, pasta.execute.trajopt): the chain's segments and poses, the executed
chain being the optimised rollout, the contact term's pull, determinism, the session and bad settings.

Scene: crs's validation instance 2000 (cut, push, roll), a few env steps per segment so a test stays cheap.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch

from pasta.core.errors import ConfigError

pytestmark = pytest.mark.sim

SEED = 2000


@pytest.fixture(scope="module")
def crs():
    from pasta.plugins import get_plugins

    task = get_plugins().tasks.load("crs")(None, None)
    return task, task.instance(SEED), task.make_sim()


def _cfg(**over):
    from pasta.config.run import TrajOptConfig

    return TrajOptConfig(**{"iterations": 2, "steps": 3, **over})


def test_segments_follow_the_ground_truth_chain(crs):
    """One segment per ground-truth step, its skill's tool active at the approach pose for the recorded piece
    and sub-goal, the previous segment's tool parked."""
    from pasta.execute.trajopt import chain_segments
    from pasta.tasks.step import approach_pose

    task, inst, sim = crs
    segs = chain_segments(task, inst, sim)
    assert [s.skill for s in segs] == inst.skeleton == ["cut", "push", "roll"]
    assert [s.tool for s in segs] == [task.skill(n).tool for n in inst.skeleton]
    before = inst.init_points
    want = approach_pose(task.skill("cut"), before[inst.steps[0].inputs], inst.step_goal(0), scene=before)
    np.testing.assert_allclose(segs[0].poses["knife"][:3], want.position, atol=1e-6)
    park = task.skill("cut").park_pose()
    np.testing.assert_allclose(segs[1].poses["knife"][:3], park.position, atol=1e-6)
    assert not np.allclose(segs[1].poses["pusher"][:3], segs[0].poses["pusher"][:3])  # placed for its step
    np.testing.assert_array_equal(sim.particles(), inst.init.x)  # the simulator is back at the start


def test_executed_chain_is_the_optimised_rollout(crs):
    """What the optimiser saw is what the forward simulator executes: bitwise the same particles."""
    from pasta.execute.trajopt import chain_segments, execute_chain
    from pasta.sim.grad import chain_rows, rollout_rows

    task, inst, sim = crs
    segs = chain_segments(task, inst, sim)
    rng = np.random.default_rng(0)
    acts = [rng.uniform(-1, 1, size=(3, sim.tool_spec(s.tool).action_dim)) for s in segs]
    rows = chain_rows(sim, [({s.tool: torch.as_tensor(a)}, {k: torch.as_tensor(v) for k, v in s.poses.items()})
                            for s, a in zip(segs, acts)])
    x = rollout_rows(sim, rows).numpy()
    execute_chain(sim, inst, segs, acts, idle_steps=0)
    np.testing.assert_array_equal(sim.particles(), x)
    sim.set_state(inst.init)


def test_contact_pulls_the_knife_down_to_the_dough(crs):
    """Zero actions touch nothing, so the shape loss has no gradient; the contact term's does: the knife,
    above the dough, is pulled down (d loss / d vertical action > 0 in every step but the last, whose motion
    ends after the last distance measured at a step's start)."""
    from pasta.execute.trajopt import chain_segments
    from pasta.sim.trajopt import _contact
    from pasta.sim.grad import chain_rows, rollout_rows

    task, inst, sim = crs
    segs = chain_segments(task, inst, sim)[:1]
    knife = torch.zeros(3, sim.tool_spec("knife").action_dim, dtype=torch.float64, requires_grad=True)
    rows = chain_rows(sim, [({"knife": knife}, {k: torch.as_tensor(v) for k, v in segs[0].poses.items()})])
    xs = rollout_rows(sim, rows, every_step=True)
    _contact(sim, rows, xs, segs, 3).backward()
    y = list(sim.tool_spec("knife").channels).index("y")
    assert (knife.grad[:-1, y] > 0).all() and (knife.grad[-1] == 0).all(), knife.grad


def test_episode_is_reproducible_and_recorded(crs):
    """Two runs with one seed give the same losses, actions and score; the session records the iterations."""
    from pasta.execute.session import build_session
    from pasta.execute.trajopt import run_trajopt

    task, inst, sim = crs
    a = run_trajopt(task, inst, _cfg(), sim=sim, seed=1)
    b = run_trajopt(task, inst, _cfg(), sim=sim, seed=1)
    assert len(a.losses) == 2 and a.losses == b.losses and np.isfinite(a.losses).all()
    for x, y in zip(a.actions, b.actions):
        np.testing.assert_array_equal(x, y)
    assert a.score.improvement == b.score.improvement
    assert any(np.any(x != 0) for x in a.actions) or a.best_iteration == 0

    session = build_session("crs", method="trajopt", trajopt={"iterations": 1, "steps": 2})
    out = session.episode(SEED, sim=sim)
    row = out.to_dict()
    assert row["method"] == "trajopt" and len(row["trajopt"]["losses"]) == 1
    assert row["trajopt"]["skills"] == ["cut", "push", "roll"] and out.plan_s > 0
    setup = session.describe()
    assert setup["planner"] is None and setup["controller"] == "trajopt" and setup["weights"] == {}


def test_pasta_run_reports_the_optimisation(crs, tmp_path, capsys):
    from pasta.cli import main

    png = tmp_path / "summary.png"
    assert main(["run", "task=crs", f"seed={SEED}", "method=trajopt", "trajopt.iterations=1", "trajopt.steps=2",
                 f"summary={png}"]) == 0
    out = capsys.readouterr().out
    assert "Traj-Opt (cut -> push -> roll): 1 iterations" in out and "(trajopt): normalised improvement" in out
    assert png.stat().st_size > 0


@pytest.mark.parametrize("key,value", [("iterations", -1), ("lr", 0), ("steps", 0), ("points", 2), ("blur", 0)])
def test_bad_settings_are_refused(key, value):
    from pasta.config import load_config

    with pytest.raises(ConfigError, match=f"trajopt.{key}"):
        load_config(["task=crs", "method=trajopt", f"trajopt.{key}={value}"])
