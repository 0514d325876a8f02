"""The tasks as Gymnasium environments (issue 43): every registered task passes Gymnasium's own checker,
a seed reproduces an episode bit for bit, the rewards add up to the task's normalised improvement, the picture
has the shape Gymnasium expects, and a vector env over processes steps."""

from __future__ import annotations

import numpy as np
import pytest

gymnasium = pytest.importorskip("gymnasium")  # in the dev extra: installed by make test and CI

from pasta.envs import TaskEnv, env_id, register_envs  # noqa: E402
from pasta.plugins import get_plugins  # noqa: E402

pytestmark = pytest.mark.sim
SEEDS = (1000,)  # the first test config of each task: generated once into the task cache


@pytest.mark.parametrize("task", get_plugins().tasks.names())
def test_every_registered_task_is_an_env_that_passes_check_env(task):
    from gymnasium.utils.env_checker import check_env

    assert env_id(task) in register_envs()
    env = gymnasium.make(env_id(task), seeds=SEEDS)
    check_env(env.unwrapped, skip_render_check=True)
    obs, info = env.reset(seed=0)
    assert obs["dough"].shape == obs["goal"].shape == (512, 3) and obs["tools"].shape[1] == 7
    assert env.action_space.shape == (len(env.unwrapped.action_layout),) and info["instance"] == 1000
    env.close()


def _episode(seed: int, steps: int = 12):
    env = TaskEnv("push", seeds=SEEDS)
    obs, _ = env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    out, rewards, info = [obs], [], {}
    for _ in range(steps):
        obs, reward, terminated, truncated, info = env.step(rng.uniform(-1, 1, env.action_space.shape))
        out.append(obs)
        rewards.append(reward)
    return out, rewards, info


def test_a_seed_reproduces_an_episode_bit_for_bit_and_rewards_add_up_to_the_improvement():
    a, ra, info = _episode(3)
    b, rb, _ = _episode(3)
    assert ra == rb and all(all(np.array_equal(x[k], y[k]) for k in x) for x, y in zip(a, b))
    assert sum(ra) == pytest.approx(info["improvement"], abs=1e-9)
    c, _, _ = _episode(4, steps=0)
    assert not np.array_equal(a[0]["dough"], c[0]["dough"])  # another seed draws other observed particles


def test_rgb_array_render_shows_dough_and_goal():
    env = TaskEnv("crs", seeds=SEEDS, render_mode="rgb_array")
    env.reset(seed=0)
    img = env.render()
    assert img.dtype == np.uint8 and img.ndim == 3 and img.shape[2] == 3 and min(img.shape[:2]) >= 200
    navy = (np.abs(img.astype(int) - [31, 58, 100]).sum(2) < 40).sum()  # the dough's colour
    assert navy > 500 and (img < 250).any(2).mean() < 0.5  # drawn, on a mostly white picture
    assert TaskEnv("crs", seeds=SEEDS).render() is None  # no render mode: nothing


def _make_push():
    import gymnasium

    import pasta.envs  # noqa: F401 - registers the ids in the spawned process

    return gymnasium.make("pasta/push-v0", seeds=SEEDS)


def test_a_vector_env_over_processes_steps():
    # spawn: a forked child of a process whose Taichi runtime is up deadlocks
    envs = gymnasium.vector.AsyncVectorEnv([_make_push] * 2, context="spawn")
    try:
        obs, _ = envs.reset(seed=0)
        assert obs["dough"].shape == (2, 512, 3)
        obs, rewards, terminated, truncated, _ = envs.step(envs.action_space.sample())
        assert rewards.shape == (2,) and np.isfinite(rewards).all()
    finally:
        envs.close()


def test_a_vector_env_over_ray_actors_steps_like_the_environments_it_holds():
    pytest.importorskip("ray")  # CI installs the Ray extra (.ci/run), so this runs there
    from pasta.envs import RayVectorEnv

    envs = RayVectorEnv("push", 2, num_cpus=2, seeds=SEEDS)
    try:
        obs, infos = envs.reset(seed=5)
        assert obs["dough"].shape == (2, 512, 3) and envs.observation_space.contains(obs)
        assert infos["instance"].tolist() == [SEEDS[0]] * 2 and infos["_instance"].all()
        local = TaskEnv("push", seeds=SEEDS)
        for i in range(2):  # environment i is seeded with seed + i, exactly as a TaskEnv of its own
            assert np.array_equal(obs["dough"][i], local.reset(seed=5 + i)[0]["dough"])
        actions = envs.action_space.sample()
        obs, rewards, terminated, truncated, _ = envs.step(actions)
        expected = local.step(actions[1])  # the local env is at environment 1's state
        assert np.array_equal(obs["dough"][1], expected[0]["dough"]) and rewards[1] == expected[1]
        assert rewards.shape == (2,) and terminated.dtype == bool and truncated.shape == (2,)
    finally:
        envs.close()


def test_bad_arguments_are_named():
    from pasta.core.errors import ConfigError, PluginNotFoundError

    with pytest.raises(ConfigError, match="render_mode='human'"):
        TaskEnv("push", render_mode="human")
    with pytest.raises(PluginNotFoundError, match="unknown task 'psuh'"):
        TaskEnv("psuh")
    env = TaskEnv("push", seeds=SEEDS)
    with pytest.raises(gymnasium.error.ResetNeeded):
        env.step(np.zeros(env.action_space.shape))


def test_sac_point_trains_on_an_env_and_its_policy_acts(tmp_path):
    """A tiny budget of scripts/train_sac.py's agent: SAC updates run and the policy returns actions in the
    action space (not a score)."""
    import importlib.util
    from pathlib import Path

    import torch

    path = Path(__file__).resolve().parent.parent / "scripts" / "train_sac.py"
    spec = importlib.util.spec_from_file_location("train_sac", path)
    train_sac = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(train_sac)
    torch.manual_seed(0)
    env = gymnasium.make("pasta/push-v0", seeds=SEEDS, points=64)
    model = train_sac.make_agent(env, buffer_size=200, learning_starts=10, batch_size=8)
    before = [p.detach().clone() for p in model.policy.actor.parameters()]
    model.learn(30)
    assert any(not torch.equal(a, b) for a, b in zip(before, model.policy.actor.parameters()))  # it trained
    obs, _ = env.reset(seed=1)
    action, _ = model.predict(obs, deterministic=True)
    assert env.action_space.contains(action.astype(np.float32))


def test_sac_point_checkpoints_resume_a_killed_run(tmp_path):
    """scripts/train_sac.py's checkpoint (safetensors + npz + JSON, no pickle) restores the networks, optimisers,
    replay buffer and counters; two runs resumed from one checkpoint train to the same weights."""
    import importlib.util
    from pathlib import Path

    import torch

    path = Path(__file__).resolve().parent.parent / "scripts" / "train_sac.py"
    spec = importlib.util.spec_from_file_location("train_sac", path)
    train_sac = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(train_sac)
    settings = {"task": "push", "seed": 0, "points": 64, "batch_size": 8, "train_freq": 4}

    def agent():
        env = gymnasium.make("pasta/push-v0", seeds=SEEDS, points=64)
        return train_sac.make_agent(env, buffer_size=200, learning_starts=10, batch_size=8)

    first = agent()
    (tmp_path / "during").mkdir()
    first.learn(20, callback=train_sac.Curve(20, tmp_path / "during", every=0, checkpoint_every=20, settings=settings))
    folder = tmp_path / "during" / "checkpoint"  # written by the callback at env step 20
    assert sorted(p.name for p in folder.iterdir()) == ["buffer.npz", "model.safetensors", "state.json"]
    train_sac.save_checkpoint(first, tmp_path / "checkpoint", settings)  # after the step's update
    saved = {k: v.clone() for k, v in first.policy.state_dict().items()}
    weights = []
    for _ in range(2):
        resumed = agent()
        assert train_sac.load_checkpoint(resumed, tmp_path / "checkpoint", settings) == 20
        state = resumed.policy.state_dict()
        assert all(torch.equal(saved[k], state[k]) for k in saved)
        assert resumed.replay_buffer.pos == 20
        np.testing.assert_array_equal(resumed.replay_buffer.actions[:20], first.replay_buffer.actions[:20])
        resumed.learn(8, reset_num_timesteps=False)
        assert resumed.num_timesteps == 28
        weights.append([p.detach().clone() for p in resumed.policy.parameters()])
    assert all(torch.equal(a, b) for a, b in zip(*weights))  # reproducible from the checkpoint
    assert any(not torch.equal(a, saved_a) for a, saved_a in zip(weights[0], first.policy.parameters()))  # it trained
    with pytest.raises(SystemExit, match="other settings"):
        train_sac.load_checkpoint(agent(), tmp_path / "checkpoint", {**settings, "points": 128})
