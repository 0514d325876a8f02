"""The plan executor: attention (pure), goals, the step monitor's decisions and a 1-step plan on a tiny simulated scene."""

import argparse

import numpy as np
import pytest
import torch

from pasta.config import PerceptionConfig
from pasta.core import Controller, Encoder, Stop
from pasta.core.plan import Plan, PlanStep, as_latents
from pasta.execute import ExecuteConfig, attend, execute_plan
from pasta.plugins import get_plugins


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
    sim = Simulator(cfg, tools=get_plugins().simulated_tools())
    obs = sim.reset(crs_dough(cfg.n_particles, rng=3, floor_y=sim.floor_y, length=0.2))
    center = obs.dough.mean(0).tolist()
    goal = obs.dough - np.array([0.03, 0.0, 0.0], np.float32)
    skill = nudge
    path = tmp_path / "run.mcap"
    with RunLogger(path) as log:
        res = execute_plan(sim, one_step_plan(center, 0.03), skills={"nudge": skill}, encoder=box_encoder, goal=goal,
                           cfg=ExecuteConfig(controller="heuristic", idle_steps=2), perception=PerceptionConfig(num_points=200),
                           logger=log)
    assert len(res.steps) == 1
    info = res.steps[0]
    assert info.skill == "nudge" and info.attended == (0,) and info.env_steps == 4 and info.ended == "done"
    assert info.piece_points == 300 and info.attempts == 1
    assert sim.step_count == 6  # 4 controller steps + 2 idle
    np.testing.assert_allclose(sim.tool_pose("pusher")[:3], [0.45, 0.8, 0.12], atol=1e-6)  # parked
    assert np.isfinite(res.normalized_improvement) and res.normalized_improvement > 0  # the dough moved towards -x
    # what the summary image draws: the dough after the step, the pusher where its motion ended (not parked)
    [snap] = res.snapshots
    np.testing.assert_array_equal(snap.dough, res.final_dough)
    assert snap.tool == "pusher" and snap.path.shape == (5, 3)  # approach + 4 controller steps
    pusher = [t for t in snap.tools if t.name == "pusher"]
    assert len(pusher) == 1 and np.allclose(pusher[0].position, snap.path[-1], atol=1e-6)
    assert not np.allclose(pusher[0].position, [0.45, 0.8, 0.12])
    assert {t.name for t in res.start_tools} == {t.name for t in res.end_tools} == {t.name for t in snap.tools}

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

    class Short(type(nudge)):
        max_steps = 3  # the skill's step limit

    cfg = SimConfig(n_grid=32, max_particles=1500, n_particles=1500, obs_points=300, seed=3)
    sim = Simulator(cfg, tools=get_plugins().simulated_tools())
    obs = sim.reset(crs_dough(cfg.n_particles, rng=4, floor_y=sim.floor_y, length=0.2))
    torch.manual_seed(0)
    net = PolicyNet(PolicyConfig(action_dim=4, dough_points=64, tool_points=20, goal_points=64, head_widths=(16,),
                                 encoder=PointNet2Config(levels=[SAConfig(16, 0.1, 8, (16,))], global_widths=(32,))))
    skill = Short()
    skill.attach_policy(LearnedPolicy(net, "nudge", done_threshold=1.0))  # never done: runs to the skill's limit
    goal = obs.dough - np.array([0.06, 0.0, 0.0], np.float32)
    res = execute_plan(sim, one_step_plan(obs.dough.mean(0).tolist(), 0.06), skills={"nudge": skill}, encoder=box_encoder,
                       goal=goal, cfg=ExecuteConfig(controller="learned", idle_steps=1, retries=0),
                       perception=PerceptionConfig(num_points=64))
    assert res.steps[0].env_steps == 3 and res.steps[0].ended == "limit" and sim.step_count == 4


class _Watched(Controller):
    """Pushes -x for 4 steps like the nudge's heuristic, but asks the monitor to watch it (as a learned policy does)."""

    watch = True

    def __init__(self):
        self.i = 0

    def act(self, obs):
        self.i += 1
        return np.array([-1.0, 0.0, 0.0, 0.0], np.float32), self.i >= 4


@pytest.mark.sim
def test_the_monitor_skips_a_watched_step_whose_piece_is_at_its_goal_and_says_so(tmp_path, nudge, box_encoder,
                                                                                  one_step_plan):
    from pasta.io import RunLogger, RunReader
    from pasta.sim import SimConfig, Simulator, crs_dough

    class WatchedNudge(type(nudge)):
        def policy(self):
            return _Watched()

    cfg = SimConfig(n_grid=32, max_particles=1500, n_particles=1500, obs_points=300, seed=3)
    sim = Simulator(cfg, tools=get_plugins().simulated_tools())
    steps = {}
    class UnfinishedNudge(WatchedNudge):
        def unfinished(self, piece, goal):
            return True  # its own measure says the piece still needs it

    for controller, skill in (("learned", WatchedNudge()), ("heuristic", nudge), ("unfinished", UnfinishedNudge())):
        obs = sim.reset(crs_dough(cfg.n_particles, rng=4, floor_y=sim.floor_y, length=0.2))
        # the goal is the observed dough: the step's goal piece is where the piece already is
        with RunLogger(tmp_path / f"{controller}.mcap") as log:
            res = execute_plan(sim, one_step_plan(obs.dough.mean(0).tolist(), 0.03), skills={"nudge": skill},
                               encoder=box_encoder, goal=obs.dough, logger=log,
                               cfg=ExecuteConfig(controller="heuristic" if controller == "heuristic" else "learned",
                                                 idle_steps=1, retries=0),
                               perception=PerceptionConfig(num_points=64))
        steps[controller] = res.steps[0]
    assert steps["learned"].ended == "at_goal" and steps["learned"].env_steps == 0 and steps["learned"].attempts == 0
    assert "skipped: the piece already is at its goal" in steps["learned"].describe()
    lines = [m.text for _, m in RunReader(tmp_path / "learned.mcap").messages("/log")]
    assert any("nudge skipped: the piece already is at its goal" in m for m in lines), lines
    # a trusted (heuristic) controller is not watched: it runs to its own done
    assert steps["heuristic"].ended == "done" and steps["heuristic"].env_steps == 4
    # a watched step at its goal by distance that its skill calls unfinished is started
    assert steps["unfinished"].ended != "at_goal" and steps["unfinished"].env_steps > 0


@pytest.mark.sim
def test_a_watched_step_that_changes_its_piece_a_little_but_really_executes(nudge, box_encoder, one_step_plan):
    """A skill whose step moves its piece by a Chamfer distance of 5e-4 to 1e-3 (a press, a short nudge) runs
    with a learned (watched) controller: only a piece within perception.unchanged_threshold (5e-4) of its
    goal is at its goal. The rule before (regress_near, 1e-3) skipped it silently."""
    from pasta.sim import SimConfig, Simulator, crs_dough
    from pasta.tasks.step import GoalMonitor

    class WatchedNudge(type(nudge)):
        def policy(self):
            return _Watched()

    cfg = SimConfig(n_grid=32, max_particles=1500, n_particles=1500, obs_points=300, seed=3)
    sim = Simulator(cfg, tools=get_plugins().simulated_tools())
    obs = sim.reset(crs_dough(cfg.n_particles, rng=4, floor_y=sim.floor_y, length=0.2))
    goal = obs.dough - np.array([0.05, 0.0, 0.0], np.float32)
    d = GoalMonitor().distance(obs.dough, goal)
    assert 5e-4 < d < 1e-3, d  # a small but real change
    assert GoalMonitor(at_goal=1e-3).should_run(obs.dough, goal, keeps_count=True, watch=True) is Stop.AT_GOAL
    res = execute_plan(sim, one_step_plan(obs.dough.mean(0).tolist(), 0.05), skills={"nudge": WatchedNudge()},
                       encoder=box_encoder, goal=goal, cfg=ExecuteConfig(controller="learned", idle_steps=1, retries=0),
                       perception=PerceptionConfig(num_points=64))
    assert res.steps[0].ended != "at_goal" and res.steps[0].env_steps > 0 and res.steps[0].attempts == 1


@pytest.mark.sim
def test_the_monitor_never_skips_a_step_that_changes_the_piece_count(nudge, box_encoder):
    from pasta.core import SkillSpec
    from pasta.sim import SimConfig, Simulator, crs_dough

    class WatchedNudge(type(nudge)):
        def policy(self):
            return _Watched()

    class Halve(WatchedNudge):  # 1 -> 2, like a cut
        spec = SkillSpec("halve", 1, 2, "pusher", "test skill")

    cfg = SimConfig(n_grid=32, max_particles=1500, n_particles=1500, obs_points=300, seed=3)
    sim = Simulator(cfg, tools=get_plugins().simulated_tools())
    ended = {}
    for skill, outputs in ((WatchedNudge(), 1), (Halve(), 2)):
        obs = sim.reset(crs_dough(cfg.n_particles, rng=4, floor_y=sim.floor_y, length=0.2))
        u = [0.0, 0.0, *obs.dough.mean(0).tolist()]
        step = PlanStep(skill.name, (0,), as_latents([u] * outputs), 1.0, as_latents([u] * outputs))
        plan = Plan((step,), as_latents([u]), as_latents([u] * outputs), 0.0, 1.0, "hand", 0)
        exe = ExecuteConfig(controller="learned", goal="decoded", idle_steps=1, retries=0)
        res = execute_plan(sim, plan, skills={skill.name: skill}, encoder=box_encoder, goal=obs.dough, cfg=exe,
                           perception=PerceptionConfig(num_points=64, unchanged_threshold=1.0))  # every piece "at its goal"
        ended[skill.name] = res.steps[0].ended
    assert ended["nudge"] == "at_goal" and ended["halve"] != "at_goal"


class _TwoBoxDecoder(Encoder):
    """Decodes latent ``i`` into a box of x-length ``latents[i, 0]`` (uniform points, fixed seed)."""

    z_dim = 0

    def encode(self, points):
        raise NotImplementedError

    def sample_prior(self, n, generator):
        raise NotImplementedError

    def decode(self, latents, num_points):
        rng = np.random.default_rng(0)
        out = []
        for u in np.asarray(latents):
            out.append(rng.uniform(0, 1, (num_points, 3)) * np.array([u[0], 0.08, 0.08]))
        return torch.as_tensor(np.stack(out), dtype=torch.float32)


def test_decoded_goal_keeps_observation_density_by_volume():
    from pasta.execute import equalise_density

    latents = np.array([[0.3, 0.0], [0.1, 0.0]], np.float32)
    same = _TwoBoxDecoder().decode_clouds(latents, 2000)
    assert [len(c) for c in same] == [2000, 2000]
    big, small = equalise_density(same, 2000)
    assert len(big) == 2000
    assert 0.25 < len(small) / len(big) < 0.42  # a third of the volume
    big, small = equalise_density([same[0][:500], same[1]], 2000)  # too few points: repeated
    assert len(big) == 2000 and np.array_equal(big[500:1000], big[:500])


def test_goal_descendants_follow_single_entity_steps():
    from pasta.core.plan import Plan
    from pasta.execute import goal_descendants

    lat = lambda k: [[float(i)] * 2 for i in range(k)]  # noqa: E731
    plan = lambda steps, k: Plan(steps=tuple(steps), initial=lat(1), goal=lat(k), final_cost=0.0, score=1.0,  # noqa: E731
                                 planner="t", seed=0)
    # crs: cut 0 -> (a, b); push a; roll it. Final set: [rolled, b]
    crs = plan([PlanStep("cut", (0,), lat(2), 1.0, lat(2)), PlanStep("push", (0,), lat(1), 1.0, lat(2)),
                PlanStep("roll", (0,), lat(1), 1.0, lat(2))], 2)
    assert goal_descendants(crs, 0) == {0: ((0,), ("push", "roll")), 1: ((1,), ())}
    assert goal_descendants(crs, 1) == {0: ((0,), ("roll",))}
    assert goal_descendants(crs, 2) == {0: ((0,), ())}
    # cut twice: the first cut's left part is cut again into the final set's first two entities
    twice = plan([PlanStep("cut", (0,), lat(2), 1.0, lat(2)), PlanStep("cut", (0,), lat(2), 1.0, lat(3))], 3)
    assert goal_descendants(twice, 0) == {0: ((0, 1), ("cut",)), 1: ((2,), ())}
    assert goal_descendants(twice, 1) == {0: ((0,), ()), 1: ((1,), ())}
    # a merge adds another entity's dough: what goes into it has no goal pieces of its own
    merge = plan([PlanStep("cut", (0,), lat(2), 1.0, lat(2)), PlanStep("merge", (0, 1), lat(1), 1.0, lat(1))], 1)
    assert goal_descendants(merge, 0) == {}
    assert goal_descendants(merge, 1) == {0: ((0,), ())}


def test_anchor_moves_a_cloud_to_its_goal_piece_horizontally():
    from pasta.execute import anchor_xz

    cloud = np.random.default_rng(0).uniform(0, 0.1, (50, 3)).astype(np.float32)
    piece = cloud[:20] + np.array([0.3, 0.2, -0.1], np.float32)
    moved = anchor_xz(cloud, piece)
    np.testing.assert_allclose(moved[:, [0, 2]].mean(0), piece[:, [0, 2]].mean(0), atol=1e-6)
    np.testing.assert_array_equal(moved[:, 1], cloud[:, 1])  # heights kept
    np.testing.assert_allclose(moved - moved.mean(0), cloud - cloud.mean(0), atol=1e-6)  # shape kept


def test_goal_masses_set_the_point_counts():
    from pasta.core.errors import InputError
    from pasta.execute import equalise_density

    same = _TwoBoxDecoder().decode_clouds(np.array([[0.3, 0.0], [0.1, 0.0]], np.float32), 1000)
    a, b = equalise_density(same, 1000, masses=[200, 600])  # masses, not the decoded volumes
    assert (len(a), len(b)) == (333, 1000)
    with pytest.raises(InputError, match="one positive mass per cloud"):
        equalise_density(same, 1000, masses=[1.0])


def test_goal_pieces_are_matched_by_centroid():
    from pasta.execute import match_goal_pieces

    goal = np.concatenate([np.full((10, 3), 0.2), np.full((5, 3), 0.8)]).astype(np.float32)
    labels = np.array([0] * 10 + [1] * 5)
    final = [[9.0, 0.79, 0.8, 0.81], [9.0, 0.21, 0.2, 0.2]]  # z_dim 1, then the centroid
    got = match_goal_pieces(final, goal, labels, z_dim=1)
    assert len(got[0]) == 5 and len(got[1]) == 10


@pytest.mark.sim
def test_executor_retries_a_step_that_hit_its_step_limit(tmp_path, nudge, box_encoder, one_step_plan):
    from pasta.io import RunLogger, RunReader
    from pasta.sim import SimConfig, Simulator, crs_dough

    class Forever(Controller):
        def act(self, obs):
            return np.array([-1.0, 0.0, 0.0, 0.0], np.float32), None  # never reports done

    class Stubborn(type(nudge)):
        max_steps = 3

        def controller(self):
            return Forever()

    cfg = SimConfig(n_grid=32, max_particles=1500, n_particles=1500, obs_points=300, seed=3)
    sim = Simulator(cfg, tools=get_plugins().simulated_tools())
    runs = {}
    for retries in (0, 1):
        obs = sim.reset(crs_dough(cfg.n_particles, rng=3, floor_y=sim.floor_y, length=0.2))
        center = obs.dough.mean(0).tolist()
        goal = obs.dough - np.array([0.03, 0.0, 0.0], np.float32)
        with RunLogger(tmp_path / f"r{retries}.mcap") as log:
            res = execute_plan(sim, one_step_plan(center, 0.03), skills={"nudge": Stubborn()}, encoder=box_encoder,
                               goal=goal, cfg=ExecuteConfig(idle_steps=1, retries=retries), logger=log,
                               perception=PerceptionConfig(num_points=200))
        runs[retries] = res.steps[0]
    assert runs[0].env_steps == 3 and runs[0].ended == "limit" and runs[0].attempts == 1
    assert runs[1].env_steps == 6 and runs[1].ended == "limit" and runs[1].attempts == 2  # one retry, then give up
    lines = [m.text for _, m in RunReader(tmp_path / "r1.mcap").messages("/log")]
    assert any("visibly failed (at the skill's step limit); attempt 2" in m for m in lines), lines
    assert any("no retries left" in m for m in lines), lines


def test_step_dependencies_follow_the_produced_entities():
    from pasta.core.plan import Plan
    from pasta.execute import step_dependencies

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
    from pasta.execute import sweep_risk

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


class _BoxEncoder(_TwoBoxDecoder):
    """Latent ``(length, cx, cy, cz)`` (``z_dim`` 1) -> a box of that x-length around that centroid."""

    z_dim = 1

    def decode(self, latents, num_points):
        rng = np.random.default_rng(0)
        out = [(rng.uniform(-0.5, 0.5, (num_points, 3)) * np.array([u[0], 0.04, 0.08]) + u[1:4]) for u in np.asarray(latents)]
        return torch.as_tensor(np.stack(out), dtype=torch.float32)


def test_step_goal_uses_goal_pieces_their_places_and_masses():
    from types import SimpleNamespace

    from pasta.core.plan import Plan
    from pasta.execute import step_goal

    skills = {"cut": SimpleNamespace(keeps_position=False), "push": SimpleNamespace(keeps_position=False),
              "roll": SimpleNamespace(keeps_position=True)}
    a, b = [0.1, 0.3, 0.04, 0.5], [0.1, 0.7, 0.04, 0.5]
    pushed, rolled = [0.1, 0.2, 0.04, 0.6], [0.2, 0.22, 0.02, 0.6]
    steps = [PlanStep("cut", (0,), [a, b], 1.0, [a, b]), PlanStep("push", (0,), [pushed], 1.0, [pushed, b]),
             PlanStep("roll", (0,), [rolled], 1.0, [rolled, b])]
    plan = Plan(steps=tuple(steps), initial=[[0.2, 0.5, 0.04, 0.5]], goal=[rolled, b], final_cost=0.0, score=1.0,
                planner="t", seed=0)
    rng = np.random.default_rng(1)
    goal_a = (rng.uniform(-0.1, 0.1, (300, 3)) + [0.25, 0.02, 0.55]).astype(np.float32)  # the rolled piece's goal
    goal_b = (rng.uniform(-0.03, 0.03, (600, 3)) + [0.7, 0.04, 0.5]).astype(np.float32)
    goal, labels = np.concatenate([goal_a, goal_b]), np.repeat([0, 1], [300, 600])
    cut_a, cut_b = step_goal(plan, 0, _BoxEncoder(), skills=skills, num_points=1000, goal=goal, goal_labels=labels)
    assert (len(cut_a), len(cut_b)) == (500, 1000)  # masses 300 : 600, not the equal decoded volumes
    np.testing.assert_array_equal(cut_b[:600], goal_b)  # b persists: its goal piece itself
    assert cut_a[:, 0].mean() == pytest.approx(0.3, abs=0.01)  # pushed later: stays where the plan cuts it
    (push,) = step_goal(plan, 1, _BoxEncoder(), skills=skills, num_points=1000, goal=goal, goal_labels=labels)
    np.testing.assert_allclose(push[:, [0, 2]].mean(0), goal_a[:, [0, 2]].mean(0), atol=1e-5)  # only rolled next: anchored

    # execute.goal=decoded: no goal labels, the plain decodings
    (push,) = step_goal(plan, 1, _BoxEncoder(), skills=skills, num_points=1000, goal=goal, goal_labels=None)
    np.testing.assert_allclose(push[:, [0, 2]].mean(0), [0.2, 0.6], atol=0.01)  # the decoding's place
    cut_a, cut_b = step_goal(plan, 0, _BoxEncoder(), skills=skills, num_points=1000, goal=goal, goal_labels=None)
    assert len(cut_a) == 1000 and len(cut_b) < 1000  # decoded volumes: b's decoding is the smaller box


def test_step_goal_masses_add_up_over_a_later_cut():
    from types import SimpleNamespace

    from pasta.core.plan import Plan
    from pasta.execute import step_goal

    skills = {"cut": SimpleNamespace(keeps_position=False)}
    a, b, a1, a2 = [0.2, 0.3, 0.04, 0.5], [0.1, 0.7, 0.04, 0.5], [0.1, 0.2, 0.04, 0.5], [0.1, 0.4, 0.04, 0.5]
    steps = [PlanStep("cut", (0,), [a, b], 1.0, [a, b]), PlanStep("cut", (0,), [a1, a2], 1.0, [a1, a2, b])]
    plan = Plan(steps=tuple(steps), initial=[[0.4, 0.5, 0.04, 0.5]], goal=[a1, a2, b], final_cost=0.0, score=1.0,
                planner="t", seed=0)
    rng = np.random.default_rng(2)
    pieces = [(rng.uniform(-0.02, 0.02, (n, 3)) + [x, 0.04, 0.5]).astype(np.float32) for n, x in ((100, 0.2), (200, 0.4), (600, 0.7))]
    goal, labels = np.concatenate(pieces), np.repeat([0, 1, 2], [100, 200, 600])
    first, second = step_goal(plan, 0, _BoxEncoder(), skills=skills, num_points=1000, goal=goal, goal_labels=labels)
    assert (len(first), len(second)) == (500, 1000)  # (100 + 200) : 600
