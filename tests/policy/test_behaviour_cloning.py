"""Behaviour cloning: hindsight labels, a tiny overfitting run through the shared loop, checkpoints."""

import numpy as np
import pytest
import torch

from pasta.core.errors import InputError
from pasta.core.skill import SkillObservation
from pasta.train.policy_data import DemoSet
from pasta.demos.data import Demo
from pasta.policy.learned import LearnedPolicy
from pasta.policy.network import PolicyConfig
from pasta.policy.pointnet2 import PointNet2Config, SAConfig
from pasta.train.policy import PolicyTrainConfig, train_policy

TINY = PolicyConfig(encoder=PointNet2Config(levels=[SAConfig(32, 0.1, 8, (32, 32))], global_widths=(64, 128)),
                    head_widths=(64,))


def _counting_demo(steps=6):
    """dough[t] is filled with the value t, so a goal cloud tells which state it came from."""
    dough = np.repeat(np.arange(steps + 1, dtype=np.float32)[:, None, None], 10, 1).repeat(3, 2)
    return Demo("push", 0, dough, np.zeros((steps + 1, 4, 3), np.float32), np.zeros((steps + 1, 7), np.float32),
                np.zeros((steps, 2), np.float32))


@pytest.mark.parametrize("ratio", [0.0, 0.5, 1.0])
def test_done_label_belongs_to_the_goal_chosen(ratio):
    demo = _counting_demo()
    ds = DemoSet([demo], dough_points=5, tool_points=2, goal_points=5, hindsight_ratio=ratio, noise=0.0)
    rng = np.random.default_rng(0)
    b = ds.sample(rng.integers(0, len(ds), 400), rng)
    t = b.dough[:, 0, 0]
    g = b.goal[:, 0, 0]  # index of the goal state
    assert (g > t).all()
    np.testing.assert_array_equal(b.done, (g == t + 1).astype(np.float32))
    if ratio == 0.0:  # the final goal only: done exactly at the last action
        assert (g == 6).all()
        np.testing.assert_array_equal(b.done, (t == 5).astype(np.float32))
    else:
        assert (g < 6).any()


def test_decoded_goals_replace_final_goals_only_and_shift_them():
    """With decoded goals, a final-state goal is the reconstruction (shifted by at most decoded_shift per axis)
    with the given probability; hindsight goals and every label stay as they were."""
    demo = _counting_demo()
    recon = np.full((2, 10, 3), 100.0, np.float32)  # two draws of the final state's one piece, easy to tell apart
    ds = DemoSet([demo], dough_points=5, tool_points=2, goal_points=5, hindsight_ratio=0.5, noise=0.0,
                 decoded=[[(demo.dough[-1], recon)]], p_decoded=0.5, decoded_shift=0.03)
    rng = np.random.default_rng(0)
    b = ds.sample(rng.integers(0, len(ds), 600), rng)
    t, g = b.dough[:, 0, 0], b.goal[:, 0, 0]
    decoded = g > 50
    final = (g == 6) | decoded
    assert decoded.any() and (g == 6).any()  # both kinds of final goal
    assert 0.3 < decoded.sum() / final.sum() < 0.7
    assert np.abs(b.goal[decoded] - 100.0).max() <= 0.03 + 1e-6 and np.abs(b.goal[decoded] - 100.0).max() > 0.01
    assert np.ptp(b.goal[decoded][:, :, 0], axis=1).max() < 1e-6  # one offset per piece, not per point
    np.testing.assert_array_equal(b.done[decoded], (t[decoded] == 5).astype(np.float32))
    hindsight = ~final
    np.testing.assert_array_equal(b.done[hindsight], (g[hindsight] == t[hindsight] + 1).astype(np.float32))
    with pytest.raises(InputError, match="decoded goals for 2 demonstrations"):
        DemoSet([demo], decoded=[[], []], p_decoded=0.5)


def test_decoded_goal_settings_are_checked():
    from pasta.core.errors import ConfigError
    from pasta.train.policy import policy_configs

    with pytest.raises(ConfigError, match="decoded_goals"):
        policy_configs({"decoded_goals": 1.5})
    with pytest.raises(ConfigError, match="no trained VAE there"):
        policy_configs({"decoded_goals": 0.5, "encoder_weights": "/nonexistent/vae"})


def test_noise_is_uniform_and_bounded():
    ds = DemoSet([_counting_demo()], dough_points=5, tool_points=2, goal_points=5, noise=0.005)
    rng = np.random.default_rng(1)
    b = ds.sample(np.arange(len(ds)), rng)
    dev = np.abs(b.dough - np.round(b.dough))
    assert 0.003 < dev.max() <= 0.005


def test_tiny_behaviour_cloning_overfits_one_demo(demo_dir, tmp_path):
    from pasta.train.loop import LoopConfig

    # the one-frame network (no step / pose inputs): predict takes the clouds alone
    cfg = PolicyTrainConfig(hindsight_ratio=0.0, noise=0.0, val_fraction=0.0, steps_per_epoch=25, val_batches=1,
                            dough_points=64, tool_points=20, goal_points=64, max_demos=1, step_feature=False,
                            pose_feature=False)
    loop = LoopConfig(epochs=14, batch_size=16, lr=3e-3, seed=0, progress=False)
    policy, result = train_policy("push", demo_dir, tmp_path / "out", cfg=cfg, loop=loop, network=TINY)
    assert result.best_val_loss < 0.03 * result.history[0]["val_loss"]

    data = np.load(demo_dir / "push" / "demo_00000.npz")
    dough, tool, actions = data["dough"], data["tool_points"], data["action"]
    steps = len(actions)
    pred, done = policy.predict(dough[:-1], tool[:-1], np.repeat(dough[-1:], steps, 0))
    assert np.abs(pred - actions).mean() < 0.05 and np.abs(pred - actions).max() < 0.2
    assert done[-1] > 0.5 and (done[:-1] < 0.5).all()

    # the checkpoint written by the shared loop reloads to the same policy
    loaded = LearnedPolicy.load(tmp_path / "out", "push")
    pred2, _ = loaded.predict(dough[:-1], tool[:-1], np.repeat(dough[-1:], steps, 0))
    np.testing.assert_allclose(pred2, pred, atol=1e-6)


def test_controller_checks_skill_and_returns_action(demo_dir):
    from pasta.policy.network import PolicyNet

    class _Push:
        name = "push"

    class _Cut:
        name = "cut"

    torch.manual_seed(0)
    net = PolicyNet(PolicyConfig(action_dim=2, dough_points=16, tool_points=8, goal_points=16, encoder=TINY.encoder,
                                 head_widths=(16,)))
    policy = LearnedPolicy(net, "push", min_steps=2, done_threshold=0.0)
    with pytest.raises(InputError):
        policy.controller(_Cut())
    ctl = policy.controller(_Push())
    obs = SkillObservation(piece=np.random.rand(40, 3).astype(np.float32), goal=np.random.rand(30, 3).astype(np.float32),
                           tool_points=np.random.rand(5, 3).astype(np.float32), tool_pose=np.zeros(7, np.float32))
    ctl.reset(obs)
    a1, d1 = ctl.act(obs)
    a2, d2 = ctl.act(obs)
    assert a1.shape == (2,) and a1.dtype == np.float32 and np.abs(a1).max() <= 1
    assert not d1 and d2  # threshold 0: done as soon as min_steps allows


def test_make_task_decodes_the_final_goals_with_the_shipped_vae(demo_dir):
    from pasta.train.policy import make_task

    cfg = PolicyTrainConfig(hindsight_ratio=0.0, noise=0.0, val_fraction=0.0, val_batches=1, dough_points=32,
                            tool_points=8, goal_points=32, max_demos=1, decoded_goals=1.0, decoded_noise=0.5)
    task = make_task("push", demo_dir, cfg, network=TINY, batch_size=4)
    (pieces,) = task.train_set.decoded
    exact, recs = pieces[0]
    final = task.train_set.demos[0].dough[-1]
    assert recs.shape == (4, len(exact), 3) and len(exact) <= len(final)  # four noisy decodings of the piece
    assert not np.allclose(recs[0], exact)
    b = task.train_set.sample(np.zeros(8, int), np.random.default_rng(0))
    assert not any(np.isin(g, final).all() for g in b.goal)  # every final goal is a decoding
