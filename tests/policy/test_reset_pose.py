"""The learned reset (start) pose: the regressor fits a tiny set, it round-trips through a checkpoint
beside the policy, and a policy directory without one loads and starts as before."""

import numpy as np
import pytest
import torch

from pasta.core import Encoder, ToolPose
from pasta.core.skill import SkillObservation
from pasta.io.checkpoint import save_checkpoint
from pasta.policy.learned import LearnedPolicy, PolicyController
from pasta.policy.network import PolicyConfig, PolicyNet
from pasta.policy.pointnet2 import PointNet2Config, SAConfig
from pasta.policy.reset import MODULE, NAME, ResetConfig, ResetPose, ResetPoseNet, load_reset, reset_inputs
from pasta.train.loop import LoopConfig
from pasta.train.reset import align_offset, train_reset
from pasta.demos.data import Demo

def _loop(epochs, batch_size=32, lr=1e-3):
    """The shared loop's settings for a tiny fit (seed 0, no progress bar)."""
    return LoopConfig(epochs=epochs, batch_size=batch_size, lr=lr, seed=0, progress=False)


TINY = dict(encoder=PointNet2Config(levels=[SAConfig(16, 0.1, 8, (16, 16))], global_widths=(32, 64)), head_widths=(64,))


def _cut_demo(i, rng, points=60):
    """A bar; the goal is the bar split at a random x (left part moved left); the knife aligns to the
    split in ``k`` x-steps, then descends."""
    x0 = rng.uniform(0.4, 0.6)
    bar = np.c_[rng.uniform(x0 - 0.1, x0 + 0.1, points), rng.uniform(0, 0.04, points), rng.uniform(0.45, 0.55, points)]
    cut = x0 + rng.uniform(-0.05, 0.05)
    goal = bar.copy()
    goal[goal[:, 0] < cut, 0] -= 0.05
    k = int(rng.integers(1, 3))
    pose = np.zeros((k + 3, 7), np.float32)
    pose[:, 0] = np.r_[np.linspace(bar[:, 0].mean(), cut, k + 1), [cut, cut]]
    action = np.zeros((k + 2, 2), np.float32)
    action[:k, 0] = 0.5
    action[k:, 1] = -1.0
    dough = np.repeat(bar[None].astype(np.float32), k + 3, 0)
    dough[-1] = goal
    return Demo("cut", i, dough, np.zeros((k + 3, 5, 3), np.float32), pose, action), cut - bar[:, 0].mean()


def test_align_offset_is_the_first_vertical_step():
    demo, off = _cut_demo(0, np.random.default_rng(0))
    got, k = align_offset(demo)
    assert np.isclose(got, off, atol=1e-5)
    assert demo.action[k, 1] != 0 and not np.any(demo.action[:k, 1])


def test_regressor_overfits_a_tiny_set(tmp_path):
    rng = np.random.default_rng(0)
    demos = [_cut_demo(i, rng)[0] for i in range(6)]
    cfg = ResetConfig(points=32, widths=[32, 64], head=[64], start_step=2)
    net, metrics = train_reset(demos, [], cfg, out=tmp_path / "fit", loop=_loop(300, 6, 3e-3), noise=0.0)
    assert metrics["heldout_mae_m"] < 0.004, metrics  # targets spread over +-0.05 m
    save_checkpoint(tmp_path, module=MODULE, name=NAME, tensors=net.state_dict(), config={"skill": "cut", "network": vars(cfg)})
    reset = load_reset(tmp_path)
    assert reset.start_step == 2
    d = demos[0]
    assert abs(reset.offset(d.dough[0], d.after) - align_offset(d)[0]) < 0.01


def test_share_regressor_overfits_a_tiny_set_and_reads_back_metres(tmp_path):
    rng = np.random.default_rng(0)
    demos = [_cut_demo(i, rng, points=200)[0] for i in range(6)]
    cfg = ResetConfig(points=64, widths=[32, 64], head=[64], x_share=True, piece_share=True)
    net, metrics = train_reset(demos, [], cfg, out=tmp_path / "fit", loop=_loop(300, 6, 3e-3), noise=0.0)
    assert metrics["heldout_mae_m"] < 0.004, metrics  # reported in metres, as for an offset regressor
    save_checkpoint(tmp_path, module=MODULE, name=NAME, tensors=net.state_dict(), config={"skill": "cut", "network": vars(cfg)})
    reset = load_reset(tmp_path)
    d = demos[0]
    xs = np.asarray(d.dough[0], np.float64)[:, 0]
    share = float(reset.predict(d.dough[0], d.after)[0])
    assert 0.0 < share < 1.0 and abs(share - np.mean(xs < xs.mean() + align_offset(d)[0])) < 0.05
    assert abs(reset.offset(d.dough[0], d.after) - align_offset(d)[0]) < 0.01
    # the tool x is that quantile of the piece's x: the same share of a longer piece lands further along it
    longer = d.dough[0] * np.float32([2.0, 1.0, 1.0])
    assert np.isclose(reset.tool_x(_Skill(), longer, d.after), np.quantile(longer[:, 0], np.clip(reset.predict(longer, d.after)[0], 0, 1)))


def test_share_prior_regressor_learns_the_difference_from_the_goals_left_piece_share(tmp_path):
    from pasta.policy.reset import left_piece_share

    rng = np.random.default_rng(0)
    demos = [_cut_demo(i, rng, points=200)[0] for i in range(6)]
    cfg = ResetConfig(points=64, widths=[32, 64], head=[64], x_share=True, piece_share=True, share_prior=True)
    net, metrics = train_reset(demos, [], cfg, out=tmp_path / "fit", loop=_loop(300, 6, 3e-3), noise=0.0)
    assert metrics["heldout_mae_m"] < 0.004, metrics
    assert metrics["heldout_prior_mae_m"] < 0.004, metrics  # the goal's split alone: the bar keeps its mass
    save_checkpoint(tmp_path, module=MODULE, name=NAME, tensors=net.state_dict(), config={"skill": "cut", "network": vars(cfg)})
    reset = load_reset(tmp_path)
    d = demos[0]
    with torch.no_grad():
        raw = reset.net(torch.as_tensor(np.stack([reset_inputs(d.dough[0], d.after, 64, np.random.default_rng(0), True)[0]])))
    prior = left_piece_share(d.after)
    assert np.isclose(reset.predict(d.dough[0], d.after)[0], float(raw[0, 0]) + prior, atol=1e-6)  # the prior added back
    assert abs(float(raw[0, 0])) < 0.05  # the network's part is a small correction
    assert abs(reset.offset(d.dough[0], d.after) - align_offset(d)[0]) < 0.01


def test_left_piece_share_is_the_leftmost_pieces_share_and_a_half_for_one_piece():
    from pasta.policy.reset import left_piece_share

    left = np.c_[np.linspace(0.30, 0.38, 30), np.full(30, 0.02), np.full(30, 0.5)]
    right = np.c_[np.linspace(0.50, 0.68, 70), np.full(70, 0.02), np.full(70, 0.5)]
    assert np.isclose(left_piece_share(np.concatenate([right, left])), 0.3)  # by centroid x, not by order
    assert left_piece_share(right) == 0.5  # one piece says nothing of the split


def test_a_checkpoint_written_before_share_prior_loads_without_it(tmp_path):
    cfg = vars(ResetConfig(points=16, widths=[16], head=[16], x_share=True)).copy()
    del cfg["share_prior"]
    net = ResetPoseNet(ResetConfig(**cfg))
    save_checkpoint(tmp_path, module=MODULE, name=NAME, tensors=net.state_dict(), config={"skill": "cut", "network": cfg})
    assert load_reset(tmp_path).net.cfg.share_prior is False
    cfg["shar_prior"] = True  # any other missing or unknown key is still an error
    save_checkpoint(tmp_path, module=MODULE, name=NAME, tensors=net.state_dict(), config={"skill": "cut", "network": cfg})
    with pytest.raises(Exception, match="shar_prior"):
        load_reset(tmp_path)


def test_share_prior_needs_x_share():
    from pasta.core.errors import ConfigError
    from pasta.train.reset import reset_configs

    assert reset_configs({})[1].x_share  # the shipped regressor's: a share, with the prior (no switch of its own)
    with pytest.raises(ConfigError, match="share_prior"):
        reset_configs({"share_prior": False})
    with pytest.raises(ConfigError, match="share_prior needs x_share"):
        ResetConfig(share_prior=True)
    assert not reset_configs({"x_share": False})[1].x_share  # an offset regressor, without the prior


class _Skill:
    name = "cut"

    def approach_pose(self, piece, goal=None, scene=None):
        c = np.asarray(piece).mean(0)
        return ToolPose((float(c[0]), 0.3, float(c[2])), 0.0)


class _Reset(ResetPose):
    """A regressor that always predicts 0.02 m right of the centroid, in tool ``x``."""

    start_step = 3
    target = "tool"

    def __init__(self):
        pass

    def predict(self, piece, goal):
        return np.array([0.02])


def _policy_dir(tmp_path):
    torch.manual_seed(0)
    net = PolicyNet(PolicyConfig(action_dim=2, dough_points=16, tool_points=5, goal_points=16, step_feature=True, **TINY))
    save_checkpoint(tmp_path, module="policy", tensors=net.state_dict(),
                    config={"skill": "cut", "tool": "knife", "network": net.cfg.to_dict()})
    return net


def test_policy_without_reset_head_loads_and_starts_as_before(tmp_path):
    _policy_dir(tmp_path)
    policy = LearnedPolicy.load(tmp_path, "cut")
    assert policy.reset is None
    ctl = policy.controller(_Skill())
    piece = np.random.default_rng(0).uniform(0.4, 0.6, (30, 3)).astype(np.float32)
    assert ctl.approach_pose(piece, piece) is None  # run_skill falls back to the skill's approach pose
    obs = SkillObservation(piece=piece, goal=piece, tool_points=np.zeros((5, 3), np.float32),
                           tool_pose=np.r_[0.5, 0.3, 0.5, 1, 0, 0, 0].astype(np.float32))
    ctl.reset(obs)
    assert ctl.steps == 0


def test_reset_head_moves_the_start_pose_and_the_step_counter(tmp_path):
    _policy_dir(tmp_path)
    policy = LearnedPolicy.load(tmp_path, "cut")
    policy.reset = _Reset()
    ctl = policy.controller(_Skill())
    assert isinstance(ctl, PolicyController)
    piece = np.random.default_rng(0).uniform(0.4, 0.6, (30, 3)).astype(np.float32)
    pose = ctl.approach_pose(piece, piece)
    assert np.isclose(pose.position[0], piece[:, 0].mean() + 0.02, atol=1e-6)
    assert pose.position[1] == 0.3
    obs = SkillObservation(piece=piece, goal=piece, tool_points=np.zeros((5, 3), np.float32),
                           tool_pose=np.r_[pose.position, 1, 0, 0, 0].astype(np.float32))
    ctl.reset(obs)
    assert ctl.steps == 3
    policy.max_steps, policy.done_threshold = 2, 1.0  # the limit counts actions actually taken
    assert not ctl.act(obs)[1] and ctl.act(obs)[1]
    policy.start_step = 0  # an explicit override
    ctl.approach_pose(piece, piece)
    ctl.reset(obs)
    assert ctl.steps == 0


def test_start_at_reset_drops_the_align_phase():
    from pasta.train.policy import from_reset_pose

    demo, _ = _cut_demo(0, np.random.default_rng(3))
    _, k = align_offset(demo)
    assert k >= 1
    cut = from_reset_pose(demo)
    assert len(cut.action) == len(demo.action) - k and len(cut.dough) == len(cut.action) + 1
    assert np.all(cut.action[0] == demo.action[k]) and cut.action[0, 1] != 0  # it starts descending
    assert np.allclose(cut.tool_pose[0], demo.tool_pose[k]) and np.allclose(cut.dough[-1], demo.dough[-1])
    flat = Demo("cut", 1, demo.dough, demo.tool_points, demo.tool_pose, demo.action * np.array([1.0, 0.0], np.float32))
    assert from_reset_pose(flat) is flat  # no vertical action: kept whole


def test_reset_offset_averages_its_draws(tmp_path):
    rng = np.random.default_rng(1)
    demos = [_cut_demo(i, rng)[0] for i in range(4)]
    cfg = ResetConfig(points=16, widths=[16, 32], head=[32])
    net, _ = train_reset(demos, [], cfg, out=tmp_path / "fit", loop=_loop(3, 4))
    d = demos[0]
    one = load_reset_from(tmp_path / "one", net, cfg, draws=1).offset(d.dough[0], d.after)
    many = load_reset_from(tmp_path / "many", net, cfg, draws=8)
    from pasta.policy.reset import reset_inputs

    pts = np.stack([reset_inputs(d.dough[0], d.after, 16, np.random.default_rng(i))[0] for i in range(8)])
    with torch.no_grad():
        expected = float(net(torch.as_tensor(pts)).mean())
    assert np.isclose(many.offset(d.dough[0], d.after), expected, atol=1e-6)
    assert not np.isclose(one, expected)  # 16 of 60 points: the draws differ


def load_reset_from(directory, net, cfg, *, draws):
    from dataclasses import replace

    save_checkpoint(directory, module=MODULE, name=NAME, tensors=net.state_dict(),
                    config={"skill": "cut", "network": vars(replace(cfg, draws=draws))})
    return load_reset(directory)


class _ShiftedEffect:
    """A skill whose tool acts 3 cm right of where it stands (the learned target is the effect's x)."""

    name = "cut"

    def reset_target(self, tool_x):
        return (tool_x + 0.03,)

    def reset_tool_x(self, target):
        return target[0] - 0.03


def test_regressor_on_the_skill_target_places_the_tool_through_the_skill(tmp_path):
    rng = np.random.default_rng(0)
    demos = [_cut_demo(i, rng)[0] for i in range(6)]
    skill = _ShiftedEffect()
    cfg = ResetConfig(points=32, widths=[32, 64], head=[64], target="skill")
    net, metrics = train_reset(demos, [], cfg, out=tmp_path / "fit", loop=_loop(300, 6, 3e-3), noise=0.0, skill=skill)
    assert metrics["target"] == "skill" and metrics["heldout_tool_mae_m"] < 0.006, metrics  # a constant: ~0.025
    save_checkpoint(tmp_path, module=MODULE, name=NAME, tensors=net.state_dict(), config={"skill": "cut", "network": vars(cfg)})
    reset = load_reset(tmp_path)
    assert reset.target == "skill"
    d = demos[0]
    true_x = float(d.dough[0][:, 0].mean()) + align_offset(d)[0]
    # the network predicts the effect 3 cm right of the tool; the skill turns it back into the tool's x
    assert abs(reset.offset(d.dough[0], d.after) - (align_offset(d)[0] + 0.03)) < 0.01
    assert abs(reset.tool_x(skill, d.dough[0], d.after) - true_x) < 0.01
    with pytest.raises(ValueError, match="needs the skill"):
        train_reset(demos, [], cfg, out=tmp_path / "fit", loop=_loop(1))


def test_a_tool_target_regresses_the_tool_x_and_configs_name_every_key():
    from dataclasses import asdict

    from pasta.core.errors import ConfigError

    cfg = ResetConfig(points=32, widths=[32], head=[16])
    assert ResetConfig.from_dict(asdict(cfg)) == cfg
    with pytest.raises(ConfigError, match="reset pose network config lacks target"):
        ResetConfig.from_dict({k: v for k, v in asdict(cfg).items() if k != "target"})
    reset = ResetPose(ResetPoseNet(cfg))
    piece = np.random.default_rng(0).uniform(0.4, 0.6, (30, 3)).astype(np.float32)
    assert np.isclose(reset.tool_x(_ShiftedEffect(), piece, piece), piece[:, 0].mean() + reset.offset(piece, piece), atol=1e-6)


def test_reset_command_rejects_an_unknown_target(tmp_path):
    from pasta.train.reset import reset_command

    with pytest.raises(ValueError, match="target must be tool or skill"):
        reset_command(tmp_path, tmp_path, "cut", {"target": "plane"})


class _EffectAndSide:
    """A skill with two regressed values: the effect's x (3 cm right of the tool) and which side of 0.5
    the tool stands (unitless)."""

    name = "cut"

    def reset_target(self, tool_x):
        return (tool_x + 0.03, float(tool_x > 0.5))

    def reset_tool_x(self, target):
        return target[0] - 0.03


def test_regressor_learns_every_value_of_a_multi_value_target(tmp_path):
    rng = np.random.default_rng(0)
    demos = [_cut_demo(i, rng)[0] for i in range(6)]
    with pytest.raises(ValueError, match="1 outputs but the targets have 2 values"):
        train_reset(demos, [], ResetConfig(points=32, widths=[32], head=[16], target="skill"), out=tmp_path, loop=_loop(1), skill=_EffectAndSide())
    cfg = ResetConfig(points=32, widths=[32, 64], head=[64], target="skill", outputs=2)
    net, metrics = train_reset(demos, [], cfg, out=tmp_path / "fit", loop=_loop(300, 6, 3e-3), noise=0.0, skill=_EffectAndSide())
    assert metrics["heldout_tool_mae_m"] < 0.006 and metrics["heldout_mae_other"][0] < 0.25, metrics  # a constant: ~0.45
    reset = ResetPose(net)
    d = demos[0]
    y = reset.predict(d.dough[0], d.after)
    assert y.shape == (2,) and np.isclose(y[0], reset.offset(d.dough[0], d.after))


class _FakeEncoder(Encoder):
    """``encode`` -> the centroid; ``decode`` -> ``n`` points at that centroid (a maximal blur)."""

    z_dim = 0

    def sample_prior(self, n, generator):
        raise NotImplementedError

    def encode(self, points):
        return torch.as_tensor(np.asarray(points, np.float32).mean(1))

    def decode(self, latents, n):
        return torch.as_tensor(latents)[:, None, :].repeat(1, n, 1)


def test_decoded_goal_augmentation_replaces_whole_pieces(tmp_path):
    from pasta.train.decoded import decoded_pieces, goal_draw as _goal_draw

    rng = np.random.default_rng(0)
    bar = np.c_[np.linspace(0.4, 0.6, 200), np.full(200, 0.02), np.full(200, 0.5)].astype(np.float32)
    goal = bar.copy()
    goal[goal[:, 0] < 0.5, 0] -= 0.08  # the left part moved 8 cm: two pieces
    pieces = decoded_pieces(goal, _FakeEncoder())
    assert [len(e) for e, _ in pieces] == [100, 100] and np.allclose(pieces[0][1], pieces[0][0].mean(0))
    assert pieces[0][1].shape == (1, 100, 3)
    same = _goal_draw(goal, pieces, 0.0, rng)
    assert np.allclose(same, goal)
    blurred = _goal_draw(goal, pieces, 1.0, rng)
    assert len(blurred) == 200 and len(np.unique(blurred[:, 0])) == 2  # each piece decoded to its centroid
    mixed = [len(np.unique(_goal_draw(goal, pieces, 0.5, rng)[:, 0])) for _ in range(20)]
    assert {2, 101, 200} >= set(mixed) and len(set(mixed)) > 1  # pieces replaced one by one, at random
    with pytest.raises(ValueError, match="needs the encoder"):
        train_reset([_cut_demo(0, rng)[0]], [], ResetConfig(points=16, widths=[16], head=[16]), out=tmp_path, loop=_loop(1), decoded_goals=0.5)


def test_piece_share_input_carries_each_goal_pieces_share_of_the_points():
    from pasta.policy.reset import piece_shares, reset_inputs

    left = np.c_[np.linspace(0.30, 0.38, 30), np.full(30, 0.02), np.full(30, 0.5)]
    right = np.c_[np.linspace(0.50, 0.68, 70), np.full(70, 0.02), np.full(70, 0.5)]
    goal = np.concatenate([left, right]).astype(np.float32)
    assert np.allclose(piece_shares(goal), np.r_[np.full(30, 0.3), np.full(70, 0.7)])
    dough = np.c_[np.linspace(0.4, 0.6, 50), np.full(50, 0.02), np.full(50, 0.5)].astype(np.float32)
    pts, _ = reset_inputs(dough, goal, 40, np.random.default_rng(0), piece_share=True)
    assert pts.shape == (80, 5) and np.all(pts[:40, 4] == 0)  # dough points carry no share
    assert np.all(np.isclose(pts[40:, 4], 0.3) == (pts[40:, 0] < 0.0))  # the left piece, left of the dough centroid
    cfg = ResetConfig(points=40, widths=[16], head=[16], piece_share=True)
    assert ResetPoseNet(cfg)(torch.as_tensor(pts[None])).shape == (1, 1)


def test_noisy_decodings_vary_the_shape_and_keep_the_point_count():
    from pasta.train.decoded import decoded_pieces

    class _Shape(Encoder):
        """``z`` (1 value) stretches the piece along x: decoded length 0.1 * (1 + z)."""

        z_dim = 1

        def sample_prior(self, n, generator):
            raise NotImplementedError

        def encode(self, points):
            p = torch.as_tensor(np.asarray(points, np.float32))
            return torch.cat([torch.zeros(len(p), 1), p.mean(1)], 1)

        def decode(self, u, n):
            x = torch.linspace(-0.05, 0.05, n)[None, :, None] * (1 + u[:, None, :1])
            return torch.cat([x, torch.zeros(len(u), n, 2)], -1) + u[:, None, 1:]

    bar = np.c_[np.linspace(0.4, 0.5, 60), np.zeros(60), np.zeros(60)].astype(np.float32)
    (exact, recs), = decoded_pieces(bar, _Shape(), noise=0.5, draws=4, rng=np.random.default_rng(0))
    assert recs.shape == (4, 60, 3)
    lengths = np.ptp(recs[:, :, 0], axis=1)
    assert len(np.unique(lengths.round(4))) == 4 and np.allclose(recs[:, :, 0].mean(1), exact[:, 0].mean(), atol=1e-6)


def test_reset_trainer_uses_the_shared_loop_beside_the_policy_and_resumes(tmp_path):
    """``reset.*`` (best epoch) and ``reset_last.*`` (resume state) beside a policy's own ``model.*`` / ``last.*``:
    a longer run continues where the last one stopped, as every trainer of the shared loop does."""
    import json

    rng = np.random.default_rng(2)
    demos = [_cut_demo(i, rng)[0] for i in range(4)]
    cfg = ResetConfig(points=16, widths=[16], head=[16])
    _policy_dir(tmp_path)
    policy_files = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    train_reset(demos, [], cfg, out=tmp_path, loop=_loop(2, 4))
    state = json.loads((tmp_path / "reset_last.json").read_text())["state"]
    assert state["epoch"] == 1 and len(state["history"]) == 2
    train_reset(demos, [], cfg, out=tmp_path, loop=_loop(3, 4))
    state = json.loads((tmp_path / "reset_last.json").read_text())["state"]
    assert state["epoch"] == 2 and [h["epoch"] for h in state["history"]] == [0, 1, 2]  # epoch 2 only was run
    assert load_reset(tmp_path) is not None
    assert all((tmp_path / name).read_bytes() == data for name, data in policy_files.items())  # the policy's untouched
