"""The plan executor: attention (pure) and a 1-step plan on a tiny simulated scene."""

import argparse

import numpy as np
import pytest
import torch

from pasta.core.plan import PlanStep
from pasta.execute import ExecuteConfig, attend, execute_plan


def test_attend_first_step_by_index_later_by_nearest_centroid():
    pts = np.concatenate([np.zeros((5, 3)), np.ones((5, 3))]).astype(np.float32)
    labels = np.repeat([0, 1], 5)
    step = PlanStep("nudge", (0,), (), 1.0, ())
    planned = [[0.0, 0.0, 0.9, 0.9, 0.9], [0.0, 0.0, 0.1, 0.1, 0.1]]
    assert attend(labels, pts, step, planned, 2, first=True) == (0,)
    assert attend(labels, pts, step, planned, 2, first=False) == (1,)
    two = PlanStep("merge", (1, 0), (), 1.0, ())
    assert attend(labels, pts, two, planned, 2, first=False) == (0, 1)


@pytest.mark.sim
def test_executor_runs_one_step_plan_and_logs_a_verifiable_run(tmp_path, nudge, box_encoder, one_step_plan):
    from pasta.io import RunLogger, RunReader
    from pasta.io import replay
    from pasta.sim import SimConfig, Simulator, crs_dough

    cfg = SimConfig(n_grid=32, max_particles=1500, n_particles=1500, obs_points=300, seed=3)
    sim = Simulator(cfg)
    obs = sim.reset(crs_dough(cfg.n_particles, rng=3, floor_y=sim.floor_y, length=0.2))
    center = obs.dough.mean(0).tolist()
    goal = obs.dough - np.array([0.03, 0.0, 0.0], np.float32)
    skill = nudge
    path = tmp_path / "run.mcap"
    with RunLogger(path) as log:
        res = execute_plan(sim, one_step_plan(center, 0.03), skills={"nudge": skill}, encoder=box_encoder, goal=goal,
                           cfg=ExecuteConfig(controller="heuristic", idle_steps=2, decode_points=200), logger=log)
    assert len(res.steps) == 1
    info = res.steps[0]
    assert info.skill == "nudge" and info.attended == (0,) and info.env_steps == 4 and info.done
    assert info.piece_points == 300 and not info.skipped
    assert sim.step_count == 6  # 4 controller steps + 2 idle
    np.testing.assert_allclose(sim.tool_pose("pusher")[:3], [0.45, 0.8, 0.12], atol=1e-6)  # parked
    assert np.isfinite(res.normalized_improvement) and res.normalized_improvement > 0  # the dough moved towards -x

    r = RunReader(path)
    assert {"/plan", "/actions", "/dough", "/goal", "/entities", "/plan/subgoals", "/step", "/metrics"} <= set(r.topics())
    assert r.last("/metrics")[1]["normalized_improvement"] == pytest.approx(res.normalized_improvement)
    parser = argparse.ArgumentParser()
    replay.add_arguments(parser)
    assert replay.run(parser.parse_args([str(path), "--verify"])) == 0


@pytest.mark.sim
def test_executor_drives_the_learned_policy(nudge, box_encoder, one_step_plan):
    from pasta.policy.learned import LearnedPolicy
    from pasta.policy.network import PolicyConfig, PolicyNet
    from pasta.policy.pointnet2 import PointNet2Config, SAConfig
    from pasta.sim import SimConfig, Simulator, crs_dough

    cfg = SimConfig(n_grid=32, max_particles=1500, n_particles=1500, obs_points=300, seed=3)
    sim = Simulator(cfg)
    obs = sim.reset(crs_dough(cfg.n_particles, rng=4, floor_y=sim.floor_y, length=0.2))
    torch.manual_seed(0)
    net = PolicyNet(PolicyConfig(action_dim=4, dough_points=64, tool_points=20, goal_points=64, head_widths=(16,),
                                 encoder=PointNet2Config(levels=[SAConfig(16, 0.1, 8, (16,))], global_widths=(32,))))
    skill = nudge
    skill.attach_policy(LearnedPolicy(net, "nudge", done_threshold=1.0))  # never done: runs to max_steps
    res = execute_plan(sim, one_step_plan(obs.dough.mean(0).tolist(), 0.03), skills={"nudge": skill}, encoder=box_encoder,
                       goal=obs.dough, cfg=ExecuteConfig(controller="learned", max_steps=3, idle_steps=1, decode_points=64,
                                                         retries=0))
    assert res.steps[0].env_steps == 3 and not res.steps[0].done and sim.step_count == 4


class _TwoBoxDecoder:
    """Decodes latent ``i`` into a box of x-length ``latents[i, 0]`` (uniform points, fixed seed)."""

    def decode(self, latents, num_points):
        rng = np.random.default_rng(0)
        out = []
        for u in np.asarray(latents):
            out.append(rng.uniform(0, 1, (num_points, 3)) * np.array([u[0], 0.08, 0.08]))
        return torch.as_tensor(np.stack(out), dtype=torch.float32)


def test_decoded_goal_keeps_observation_density_by_volume():
    from pasta.execute import decode_entities, equalise_density

    latents = np.array([[0.3, 0.0], [0.1, 0.0]], np.float32)
    same = decode_entities(_TwoBoxDecoder(), latents, 2000)
    assert [len(c) for c in same] == [2000, 2000]
    big, small = equalise_density(same, 2000)
    assert len(big) == 2000
    assert 0.25 < len(small) / len(big) < 0.42  # a third of the volume
    big, small = equalise_density([same[0][:500], same[1]], 2000)  # too few points: repeated
    assert len(big) == 2000 and np.array_equal(big[500:1000], big[:500])


def test_persisting_outputs_follow_the_set_bookkeeping():
    from pasta.core.plan import Plan
    from pasta.execute import persisting_outputs

    lat = lambda k: [[float(i)] * 2 for i in range(k)]  # noqa: E731
    # crs-like: cut 0 -> (a, b); push a (index 0); roll it (index 0). Final set: [rolled, b]
    steps = [PlanStep("cut", (0,), lat(2), 1.0, lat(2)), PlanStep("push", (0,), lat(1), 1.0, lat(2)),
             PlanStep("roll", (0,), lat(1), 1.0, lat(2))]
    plan = Plan(steps=tuple(steps), initial=lat(1), goal=lat(2), final_cost=0.0, score=1.0, planner="t", seed=0)
    assert persisting_outputs(plan, 0) == {1: 1}
    assert persisting_outputs(plan, 1) == {}
    assert persisting_outputs(plan, 2) == {0: 0}


def test_goal_pieces_are_matched_by_centroid():
    from pasta.execute import match_goal_pieces

    goal = np.concatenate([np.full((10, 3), 0.2), np.full((5, 3), 0.8)]).astype(np.float32)
    labels = np.array([0] * 10 + [1] * 5)
    final = [[9.0, 0.79, 0.8, 0.81], [9.0, 0.21, 0.2, 0.2]]  # z_dim 1, then the centroid
    got = match_goal_pieces(final, goal, labels, z_dim=1)
    assert len(got[0]) == 5 and len(got[1]) == 10


@pytest.mark.sim
def test_executor_retries_a_step_that_hit_its_step_limit(nudge, box_encoder, one_step_plan):
    from pasta.sim import SimConfig, Simulator, crs_dough

    from pasta.core.skill import Controller

    class Forever(Controller):
        def act(self, obs):
            return np.array([-1.0, 0.0, 0.0, 0.0], np.float32), False  # never reports done

    class Stubborn(type(nudge)):
        def controller(self):
            return Forever()

    cfg = SimConfig(n_grid=32, max_particles=1500, n_particles=1500, obs_points=300, seed=3)
    sim = Simulator(cfg)
    runs = {}
    for retries in (0, 1):
        obs = sim.reset(crs_dough(cfg.n_particles, rng=3, floor_y=sim.floor_y, length=0.2))
        center = obs.dough.mean(0).tolist()
        goal = obs.dough - np.array([0.03, 0.0, 0.0], np.float32)
        res = execute_plan(sim, one_step_plan(center, 0.03), skills={"nudge": Stubborn()}, encoder=box_encoder,
                           goal=goal, cfg=ExecuteConfig(max_steps=3, idle_steps=1, decode_points=200, retries=retries))
        runs[retries] = res.steps[0]
    assert runs[0].env_steps == 3 and not runs[0].done
    assert runs[1].env_steps == 6 and not runs[1].done  # one retry from the new observation, then give up


def test_step_dependencies_follow_the_produced_entities():
    from pasta.core.plan import Plan
    from pasta.execute.executor import step_dependencies

    def lat(k):
        return tuple((float(i),) * 4 for i in range(k))

    # cut the dough (0) -> push piece 1 (a cut output) -> push piece 1 of that state (the other cut output)
    steps = [PlanStep("cut", (0,), lat(2), 1.0, lat(2)), PlanStep("push", (1,), lat(1), 1.0, lat(2)),
             PlanStep("push", (1,), lat(1), 1.0, lat(2))]
    plan = Plan(steps=tuple(steps), initial=lat(1), goal=lat(2), final_cost=0.0, score=1.0, planner="t", seed=0)
    assert step_dependencies(plan) == [set(), {0}, {0}]  # the two pushes are independent: either may go first
    # push the piece the first push produced: a chain
    chained = Plan(steps=(steps[0], steps[1], PlanStep("push", (0,), lat(1), 1.0, lat(2))), initial=lat(1), goal=lat(2),
                   final_cost=0.0, score=1.0, planner="t", seed=0)
    assert step_dependencies(chained) == [set(), {0}, {1}]


def test_sweep_risk_sees_pieces_in_the_way_and_the_tool_band():
    from pasta.execute.executor import sweep_risk

    rng = np.random.default_rng(0)

    def box(cx, cz, hx=0.05, hz=0.03, n=200):
        return np.stack([rng.uniform(cx - hx, cx + hx, n), rng.uniform(0, 0.05, n), rng.uniform(cz - hz, cz + hz, n)], 1)

    piece = box(0.8, 0.5)
    target = np.array([0.2, 0.5])
    assert sweep_risk(piece, target, box(0.5, 0.5)) > 0  # straight in the way
    assert sweep_risk(piece, target, box(0.95, 0.5)) == 0  # behind the piece
    assert sweep_risk(piece, target, box(0.5, 0.6)) == 0  # beside the path, clear of the piece
    assert sweep_risk(piece, target, box(0.5, 0.6), half_width=0.1) > 0  # but in the pusher paddle's band
    assert sweep_risk(piece, np.array([0.8, 0.5]), box(0.5, 0.5)) == 0  # no motion, no sweep
