"""The policy's low-dimensional inputs (``step_feature``, ``pose_feature``) and the validation-side stopping-rule sweep."""

import json

import numpy as np
import pytest
import torch

from pasta.core.errors import ConfigError
from pasta.core.skill import SkillObservation
from pasta.train.policy_data import DemoSet
from pasta.policy.learned import LearnedPolicy
from pasta.policy.network import PolicyConfig, PolicyNet
from pasta.policy.pointnet2 import PointNet2Config, SAConfig
from pasta.train.select import select_rule, stop_index
from pasta.train.policy import PolicyTrainConfig, train_policy
from pasta.demos.data import Demo

TINY = dict(encoder=PointNet2Config(levels=[SAConfig(16, 0.1, 8, (16, 16))], global_widths=(32, 64)), head_widths=(64,))


def _frozen_demo(path, steps=8, points=40, seed=0):
    """Every frame is the same (the phase is invisible); the action is +0.8 in the first half, -0.8 after
    (like the cut's knife going down and up through the same heights)."""
    rng = np.random.default_rng(seed)
    blob = (np.array([0.5, 0.05, 0.5]) + rng.normal(0, 0.02, (points, 3))).astype(np.float32)
    tool = (np.array([0.5, 0.12, 0.5]) + rng.normal(0, 0.01, (10, 3))).astype(np.float32)
    action = np.where(np.arange(steps)[:, None] < steps // 2, 0.8, -0.8).astype(np.float32) * np.ones((1, 2), np.float32)
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez(path, dough=np.repeat(blob[None], steps + 1, 0), tool_points=np.repeat(tool[None], steps + 1, 0),
             tool_pose=np.zeros((steps + 1, 7), np.float32), action=action, skill=np.array("push"),
             params=np.array(json.dumps({"seed": seed})))
    return blob, tool, action


def _replay(policy, blob, tool, steps):
    """The actions ``policy``'s controller takes on ``steps`` identical frames of ``blob`` (a push policy)."""

    class _Push:
        name = "push"

    ctl = policy.controller(_Push())
    obs = SkillObservation(piece=blob, goal=blob, tool_points=tool, tool_pose=np.zeros(7, np.float32))
    ctl.reset(obs)
    return np.stack([ctl.act(obs)[0] for _ in range(steps)])


def test_configs_round_trip_and_a_missing_key_is_an_error():
    on = PolicyConfig(action_dim=2, step_feature=True, step_scale=30.0, **TINY)
    assert PolicyConfig.from_dict(on.to_dict()) == on
    d = on.to_dict()
    d.pop("goal_feature")
    d["step_featur"] = True
    with pytest.raises(ConfigError, match="policy network config lacks goal_feature and has unknown step_featur"):
        PolicyConfig.from_dict(d)
    d = on.to_dict()
    del d["encoder"]["pos_scale"]
    with pytest.raises(ConfigError, match="encoder config lacks pos_scale"):
        PolicyConfig.from_dict(d)


def test_step_changes_the_output_only_with_the_feature():
    torch.manual_seed(0)
    dough, tool, goal = torch.rand(2, 30, 3) * 0.2, torch.rand(2, 10, 3) * 0.2, torch.rand(2, 30, 3) * 0.2
    on = PolicyNet(PolicyConfig(action_dim=2, step_feature=True, pose_feature=False, **TINY)).eval()
    with torch.no_grad():
        on.action_head[-1].weight.normal_(0, 1.0)
        a0, _ = on(dough, tool, goal, torch.zeros(2))
        a1, _ = on(dough, tool, goal, torch.full((2,), 40.0))
        assert not torch.allclose(a0, a1)
        with pytest.raises(ValueError):
            on(dough, tool, goal)
    off = PolicyNet(PolicyConfig(action_dim=2, step_feature=False, pose_feature=False, **TINY)).eval()
    with torch.no_grad():
        torch.testing.assert_close(off(dough, tool, goal, torch.zeros(2))[0], off(dough, tool, goal, torch.full((2,), 40.0))[0])


def test_batches_carry_the_step_index():
    steps = 6
    dough = np.repeat(np.arange(steps + 1, dtype=np.float32)[:, None, None], 10, 1).repeat(3, 2)
    pose = np.repeat(np.arange(steps + 1, dtype=np.float32)[:, None], 7, 1)
    demo = Demo("push", 0, dough, np.zeros((steps + 1, 4, 3), np.float32), pose, np.zeros((steps, 2), np.float32))
    ds = DemoSet([demo], dough_points=5, tool_points=2, goal_points=5, noise=0.0)
    rng = np.random.default_rng(0)
    b = ds.sample(rng.integers(0, len(ds), 50), rng)
    np.testing.assert_array_equal(b.step, b.dough[:, 0, 0])  # dough[t] is filled with t
    np.testing.assert_array_equal(b.pose, np.repeat(b.step[:, None], 7, 1))  # the tool pose of step t


def test_step_feature_learns_an_action_one_frame_cannot_tell(tmp_path):
    """Identical frames, opposite actions: with the step index the policy fits both halves, and the
    controller feeds it the number of actions taken so far."""
    from pasta.train.loop import LoopConfig

    (tmp_path / "manifest.json").write_text(json.dumps({"skills": ["push"]}))
    blob, tool, action = _frozen_demo(tmp_path / "push" / "demo_00000.npz")
    cfg = PolicyTrainConfig(hindsight_ratio=0.0, noise=0.0, val_fraction=0.0, steps_per_epoch=25, val_batches=1,
                            dough_points=32, tool_points=8, goal_points=32, step_feature=True)
    loop = LoopConfig(epochs=12, batch_size=16, lr=3e-3, seed=0, progress=False)
    policy, _ = train_policy("push", tmp_path, tmp_path / "out", cfg=cfg, loop=loop,
                             network=PolicyConfig(step_scale=2.0, **TINY))
    loaded = LearnedPolicy.load(tmp_path / "out", "push")
    assert loaded.config.step_feature and loaded.config.step_scale == 2.0

    err = np.abs(_replay(loaded, blob, tool, len(action)) - action)
    assert err.max() < 0.5 and err.mean() < 0.25  # a one-frame policy: the same output for all steps, error 0.8


def test_stop_index_follows_run_skill():
    probs = [0.1, 0.6, 0.2, 0.9]
    acts = [np.ones(2)] * 3 + [np.zeros(2)]
    assert stop_index(probs, acts, 0.5, 1) == 2  # done with a non-zero action: applied, then stop
    assert stop_index(probs, acts, 0.5, 3) == 3  # step 3 (index 3) fires with a zero action: not applied
    assert stop_index(probs, acts, 0.95, 1) == 4  # never: the whole rollout
    assert stop_index(probs, acts, 0.0, 1) == 1
    assert stop_index(probs, acts, 0.95, 1, 2) == 2  # the cap: done at the 2nd action, which is applied
    assert stop_index(probs, acts, 0.5, 1, 3) == 2  # the done head fires first


def test_checkpoint_carries_its_stopping_rule(tmp_path):
    from pasta.io.checkpoint import save_checkpoint
    from pasta.train.select import write_rule

    torch.manual_seed(0)
    net = PolicyNet(PolicyConfig(action_dim=2, dough_points=16, tool_points=8, goal_points=16, **TINY))
    save_checkpoint(tmp_path, tensors=net.state_dict(), module="policy",
                    config={"skill": "push", "tool": "pusher", "network": net.cfg.to_dict()})
    plain = LearnedPolicy.load(tmp_path, "push")
    assert (plain.done_threshold, plain.min_steps, plain.max_steps) == (0.5, 1, 0)
    write_rule(tmp_path, {"done_threshold": 2.0, "min_steps": 1, "max_steps": 3})
    policy = LearnedPolicy.load(tmp_path, "push")
    assert (policy.done_threshold, policy.max_steps) == (2.0, 3)
    assert LearnedPolicy.load(tmp_path, "push", max_steps=0).max_steps == 0  # an explicit argument wins

    class _Push:
        name = "push"

    ctl = policy.controller(_Push())
    obs = SkillObservation(piece=np.random.rand(40, 3).astype(np.float32), goal=np.random.rand(30, 3).astype(np.float32),
                           tool_points=np.random.rand(5, 3).astype(np.float32), tool_pose=np.zeros(7, np.float32))
    ctl.reset(obs)
    assert [ctl.act(obs)[1] for _ in range(3)] == [None, None, "cap"]  # threshold 2 never fires; the cap does


def test_select_rule_takes_the_best_mean():
    result = {"rules": [[0.3, 1, 0], [0.5, 1, 0], [0.7, 1, 60]], "ni": [[0.2, 0.9, 0.5], [0.4, 0.7, 0.8]]}
    assert select_rule(result) == ((0.5, 1, 0), pytest.approx(0.8))


def test_pose_feature_is_shifted_with_the_clouds_and_checked():
    torch.manual_seed(0)
    cfg = PolicyConfig(action_dim=2, pose_feature=True, step_feature=True, **TINY)
    assert cfg.aux_dim == 8 and PolicyConfig.from_dict(cfg.to_dict()) == cfg
    net = PolicyNet(cfg).eval()
    dough, tool, goal = torch.rand(1, 30, 3) * 0.2, torch.rand(1, 10, 3) * 0.2, torch.rand(1, 30, 3) * 0.2
    pose = torch.tensor([[0.1, 0.2, 0.1, 1.0, 0.0, 0.0, 0.0]])
    move = torch.tensor([0.3, 0.0, -0.2])  # the whole scene shifted in x and z: the same relative input
    with torch.no_grad():
        net.action_head[-1].weight.normal_(0, 1.0)
        a, d = net(dough, tool, goal, torch.zeros(1), pose)
        a2, d2 = net(dough + move, tool + move, goal + move, torch.zeros(1), pose + torch.cat([move, torch.zeros(4)]))
        torch.testing.assert_close(a2, a, rtol=1e-4, atol=1e-5)
        a3, _ = net(dough, tool, goal, torch.zeros(1), pose + torch.tensor([0.0, 0.05, 0, 0, 0, 0, 0]))
        assert not torch.allclose(a3, a)
        with pytest.raises(ValueError):
            net(dough, tool, goal, torch.zeros(1))
    policy = LearnedPolicy(net, "push")
    with pytest.raises(Exception):
        policy.predict(dough.numpy(), tool.numpy(), goal.numpy(), np.zeros(1))
    got, _ = policy.predict(dough.numpy(), tool.numpy(), goal.numpy(), np.zeros(1), pose.numpy())
    np.testing.assert_allclose(got, a.numpy(), atol=1e-6)


def test_goal_feature_is_the_centroid_offset_and_survives_a_scene_shift():
    torch.manual_seed(0)
    cfg = PolicyConfig(action_dim=3, step_feature=True, pose_feature=False, goal_feature=True, **TINY)
    assert cfg.aux_dim == 4 and PolicyConfig.from_dict(cfg.to_dict()) == cfg
    net = PolicyNet(cfg).eval()
    seen = []
    net.aux.register_forward_hook(lambda mod, inp, out: seen.append(inp[0].clone()))
    dough, tool, goal = torch.rand(2, 30, 3) * 0.1, torch.rand(2, 10, 3) * 0.1, torch.rand(2, 30, 3) * 0.1 + 0.2
    move = torch.tensor([0.3, 0.0, -0.2])
    with torch.no_grad():
        net.action_head[-1].weight.normal_(0, 1.0)
        a, _ = net(dough, tool, goal, torch.zeros(2))
        a2, _ = net(dough + move, tool + move, goal + move, torch.zeros(2))
    offset = (goal.mean(1) - dough.mean(1)) * cfg.encoder.pos_scale
    torch.testing.assert_close(seen[0][:, 1:], offset)  # after the step column
    torch.testing.assert_close(seen[1][:, 1:], offset, rtol=1e-5, atol=1e-5)
    torch.testing.assert_close(a2, a, rtol=1e-4, atol=1e-5)


def test_step_and_pose_inputs_are_the_defaults_every_skill_trains_with():
    """Every shipped policy sees the step and the tool pose: PolicyConfig's (and so `pasta train policy`'s)
    defaults, so no skill plugin asks for them; `pasta train policy step_feature=false` turns one off."""
    from pasta.pipeline import PipelineConfig, plan
    from pasta.plugins import get_plugins
    from pasta.train.policy import policy_configs

    assert PolicyConfig().step_feature and PolicyConfig().pose_feature and not PolicyConfig().goal_feature
    _, cfg = policy_configs({"step_feature": "false"})
    assert not cfg.step_feature and cfg.pose_feature
    for name in get_plugins().skills.names():
        asked = dict(get_plugins().skills.load(name).training_defaults.get("policy") or {})
        assert not {"step_feature", "pose_feature"} & set(asked), name
    units = plan(PipelineConfig(stages="policy"), {})
    assert units and all(u.configs[1].step_feature and u.configs[1].pose_feature for u in units)


def _alternating_demo(path, steps=12, points=40, seed=0):
    """Every frame is the same and the actions alternate (+0.8, -0.4, +0.8, ...); without the step input,
    only the previous action tells the next."""
    rng = np.random.default_rng(seed)
    blob = (np.array([0.5, 0.05, 0.5]) + rng.normal(0, 0.02, (points, 3))).astype(np.float32)
    tool = (np.array([0.5, 0.12, 0.5]) + rng.normal(0, 0.01, (10, 3))).astype(np.float32)
    action = np.where(np.arange(steps)[:, None] % 2 == 0, 0.8, -0.4).astype(np.float32) * np.ones((1, 2), np.float32)
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez(path, dough=np.repeat(blob[None], steps + 1, 0), tool_points=np.repeat(tool[None], steps + 1, 0),
             tool_pose=np.zeros((steps + 1, 7), np.float32), action=action, skill=np.array("push"),
             params=np.array(json.dumps({"seed": seed})))
    return blob, tool, action


def test_batches_carry_the_previous_action():
    steps = 5
    action = np.arange(1, steps + 1, dtype=np.float32)[:, None].repeat(2, 1)
    dough = np.repeat(np.arange(steps + 1, dtype=np.float32)[:, None, None], 10, 1).repeat(3, 2)
    demo = Demo("push", 0, dough, np.zeros((steps + 1, 4, 3), np.float32), np.zeros((steps + 1, 7), np.float32), action)
    ds = DemoSet([demo], dough_points=5, tool_points=2, goal_points=5, noise=0.0)
    rng = np.random.default_rng(0)
    b = ds.sample(rng.integers(0, len(ds), 50), rng)
    np.testing.assert_array_equal(b.prev_action[:, 0], b.step)  # action[t - 1] = t, zeros at t = 0
    np.testing.assert_array_equal(b.action[:, 0], b.step + 1)


def test_previous_action_learns_what_one_frame_and_no_step_cannot_tell(tmp_path):
    """Identical frames, actions alternating: with the previous action as input the policy fits the sequence,
    and its controller feeds back what it did (zeros first); an older checkpoint config without the switch loads
    with it off."""
    from pasta.train.loop import LoopConfig

    (tmp_path / "manifest.json").write_text(json.dumps({"skills": ["push"]}))
    blob, tool, action = _alternating_demo(tmp_path / "push" / "demo_00000.npz")
    cfg = PolicyTrainConfig(hindsight_ratio=0.0, noise=0.0, val_fraction=0.0, steps_per_epoch=25, val_batches=1,
                            dough_points=32, tool_points=8, goal_points=32, step_feature=False, pose_feature=False,
                            action_feature=True)
    loop = LoopConfig(epochs=12, batch_size=16, lr=3e-3, seed=0, progress=False)
    train_policy("push", tmp_path, tmp_path / "out", cfg=cfg, loop=loop, network=PolicyConfig(**TINY))
    loaded = LearnedPolicy.load(tmp_path / "out", "push")
    assert loaded.config.action_feature and loaded.config.aux_dim == 2

    err = np.abs(_replay(loaded, blob, tool, len(action)) - action)
    assert err.max() < 0.3  # a one-frame policy outputs one action for all steps: error 0.6 on half of them
    with pytest.raises(ValueError, match="previous action"):
        loaded.net(*(torch.as_tensor(x[None]) for x in (blob, tool, blob)))
    old = loaded.config.to_dict()
    old.pop("action_feature")
    old.pop("floor_y")
    with pytest.raises(ConfigError, match="lacks action_feature and floor_y: it was written by a pasta before 2026-12-06"):
        PolicyConfig.from_dict(old)


def test_floor_y_measures_heights_from_the_dough_bottom():
    """With floor_y the same scene raised by 5 cm (dough on a board instead of the table) gives the same output; without
    it the height is an input."""
    torch.manual_seed(0)
    dough, tool, goal = torch.rand(2, 30, 3) * 0.1, torch.rand(2, 10, 3) * 0.1 + 0.05, torch.rand(2, 30, 3) * 0.1
    pose = torch.cat([tool.mean(1), torch.tensor([[1.0, 0, 0, 0]] * 2)], -1)
    up = torch.tensor([0.0, 0.05, 0.0])
    raised = [x + up for x in (dough, tool, goal)]
    raised_pose = pose.clone()
    raised_pose[:, :3] += up
    outputs = {}
    for floor in (True, False):
        net = PolicyNet(PolicyConfig(action_dim=2, floor_y=floor, step_feature=False, **TINY)).eval()
        with torch.no_grad():
            net.action_head[-1].weight.normal_(0, 1.0)
            outputs[floor] = (net(dough, tool, goal, None, pose)[0], net(*raised, None, raised_pose)[0])
    torch.testing.assert_close(*outputs[True], atol=1e-5, rtol=1e-5)
    assert not torch.allclose(*outputs[False], atol=1e-4)
    with pytest.raises(ConfigError, match="lacks floor_y"):
        PolicyConfig.from_dict({k: v for k, v in PolicyConfig(**TINY).to_dict().items() if k != "floor_y"})
