"""Task framework pieces that need no simulator: npz files, instance round trips, piece splitting,
the skill-step executor on a stand-in simulator, registration and argument parsing."""

from __future__ import annotations

import numpy as np
import pytest

from pasta.core import Controller, InputError, SkillObservation, ToolPose
from pasta.core.errors import ConfigError, PluginNotFoundError
from pasta.tasks import GroundTruthStep, TaskInstance, get_task, run_skill, split_pieces, task_names, fixed_test_seeds
from pasta.tasks.npz import read_npz, write_npz


def test_npz_is_byte_reproducible_and_pickle_free(tmp_path):
    arrays = {"a": np.arange(12, dtype=np.float32).reshape(3, 4), "s": np.array("hello"), "j": np.array('{"x": 1}')}
    write_npz(tmp_path / "one.npz", arrays)
    write_npz(tmp_path / "two.npz", arrays)
    assert (tmp_path / "one.npz").read_bytes() == (tmp_path / "two.npz").read_bytes()
    with np.load(tmp_path / "one.npz", allow_pickle=False) as z:
        assert z["s"].shape == () and str(z["s"]) == "hello"
        np.testing.assert_array_equal(z["a"], arrays["a"])
    assert not list(tmp_path.glob(".*tmp"))
    with pytest.raises(InputError, match="pickle"):
        write_npz(tmp_path / "bad.npz", {"o": np.array([object()], dtype=object)})
    assert not (tmp_path / "bad.npz").exists()


def _fake_instance() -> TaskInstance:
    from pasta.sim import SimState

    rng = np.random.default_rng(0)
    n = 50
    init = SimState(x=rng.random((n, 3), dtype=np.float32), v=np.zeros((n, 3), np.float32),
                    F=np.tile(np.eye(3, dtype=np.float32), (n, 1, 1)), C=np.zeros((n, 3, 3), np.float32),
                    tools=np.zeros((3, 5)), obs_index=np.arange(0, n, 2), step=10)
    after = init.x + 0.1
    step = GroundTruthStep("cut", {"cut_x": 0.5, "shift": -0.07}, np.arange(25), [np.arange(10), np.arange(10, 25)], after, 33)
    return TaskInstance("cut", 1000, "abc", init, after, [step], [np.arange(25)], {"boxes": []})


def test_instance_round_trip(tmp_path):
    inst = _fake_instance()
    path = inst.save(tmp_path / "i.npz")
    back = TaskInstance.load(path)
    assert back.task == "cut" and back.seed == 1000 and back.skeleton == ["cut"]
    assert back.steps[0].params == inst.steps[0].params and back.steps[0].steps == 33
    np.testing.assert_array_equal(back.goal, inst.goal)
    np.testing.assert_array_equal(back.init.x, inst.init.x)
    np.testing.assert_array_equal(back.step_goal(0), inst.goal_state[inst.obs_index][np.arange(25)])
    assert path.read_bytes() == back.save(tmp_path / "again.npz").read_bytes()


def test_split_pieces_orders_by_x():
    rng = np.random.default_rng(1)
    right = rng.random((200, 3)) * [0.1, 0.08, 0.07] + [0.7, 0.02, 0.46]
    left = rng.random((100, 3)) * [0.1, 0.08, 0.07] + [0.5, 0.02, 0.46]
    pts = np.concatenate([right, left])
    idx = np.arange(300) + 7
    out = split_pieces(pts, idx, 2)
    assert [len(o) for o in out] == [100, 200]
    assert set(out[0]) == set(idx[200:])
    # parts closer than the DBSCAN radius: the widest x gap still splits them
    touching = np.concatenate([right - [0.08, 0, 0], left])  # a 0.02 gap: one DBSCAN cluster
    assert sorted(len(o) for o in split_pieces(touching, idx, 2)) == [100, 200]
    assert len(split_pieces(pts, idx, 1)) == 1


class _Sim:
    """Stand-in simulator: the dough never moves, tools teleport and move by actions."""

    def __init__(self) -> None:
        from types import SimpleNamespace

        self.dough = np.random.default_rng(0).random((40, 3)).astype(np.float32)
        self.pose = {"knife": np.zeros(3)}
        self.steps, self.actions, self._ns = 0, [], SimpleNamespace

    def observe(self):
        p = np.r_[self.pose["knife"], 1, 0, 0, 0].astype(np.float32)
        return self._ns(dough=self.dough, dough_index=np.arange(40), tool_poses={"knife": p},
                        tool_points={"knife": np.tile(self.pose["knife"], (5, 1)).astype(np.float32)})

    def set_tool_pose(self, name, position, yaw=0.0):
        self.pose[name] = np.asarray(position, float)

    def step(self, actions=None):
        self.steps += 1
        if actions:
            self.actions.append(actions["knife"])
            self.pose["knife"][:2] += actions["knife"] * 0.015


class _Count(Controller):
    def __init__(self, n: int, final_zero: bool) -> None:
        self.n, self.final_zero, self.seen = n, final_zero, []

    def act(self, obs: SkillObservation):
        self.seen.append(len(obs.piece))
        k = len(self.seen)
        if k == self.n:
            return (np.zeros(2) if self.final_zero else np.array([1.0, 0.0])), True
        return np.array([2.0, -1.0]), False  # clipped to [-1, 1]


def test_run_skill_loop_records_and_parks(skills):
    sim = _Sim()
    cut = skills["cut"]
    run = run_skill(sim, cut, _Count(4, final_zero=True), np.arange(10), None, idle_steps=3, record=True,
                    approach=ToolPose((0.5, 0.3, 0.5)))
    assert run.steps == 3 and run.done and sim.steps == 3 + 3
    arr = run.trajectory.arrays(2)
    assert arr["dough"].shape == (4, 40, 3) and arr["action"].shape == (3, 2) and arr["tool_pose"].shape == (4, 7)
    assert np.abs(arr["action"]).max() <= 1.0
    np.testing.assert_allclose(sim.pose["knife"], cut.park_pose().position)
    # a done with a non-zero action applies it, then stops
    sim2 = _Sim()
    run2 = run_skill(sim2, cut, _Count(2, final_zero=False), np.ones(40, bool), None, idle_steps=0, park=False,
                     approach=ToolPose((0.5, 0.3, 0.5)))
    assert run2.steps == 2 and run2.done and sim2.pose["knife"][0] != cut.park_pose().position[0]
    # the step limit
    run3 = run_skill(_Sim(), cut, _Count(100, final_zero=True), [0, 1], None, max_steps=5, idle_steps=0,
                     approach=ToolPose((0.5, 0.3, 0.5)))
    assert run3.steps == 5 and not run3.done
    with pytest.raises(InputError, match="empty"):
        run_skill(_Sim(), cut, _Count(1, True), np.zeros(40, bool), None)


@pytest.fixture
def skills():
    from pasta.plugins import get_plugins

    return {n: get_plugins().skills.create(n) for n in ("cut", "push", "roll")}


def test_registered_tasks_and_errors():
    names = task_names()
    for n in ("cut", "push", "roll", "cut_rearrange", "crs", "crs_twice", "crs_distractors"):
        assert n in names
    with pytest.raises(PluginNotFoundError, match="known tasks: crs"):
        get_task("crss")
    task = get_task("crs_twice", threshold=0.9)
    assert task.horizon == 6 and task.skeleton == ("cut", "cut", "push", "push", "roll", "roll") and task.threshold == 0.9
    assert get_task("cut_rearrange").threshold == 0.80 and get_task("crs").threshold == 0.83
    with pytest.raises(ConfigError):
        get_task("crs", nonsense=1)
    assert fixed_test_seeds(3) == [1000, 1001, 1002]


def test_cache_key_depends_on_config():
    a, b = get_task("push"), get_task("push", idle_steps=11)
    assert a.key() == get_task("push").key() != b.key()
    assert a.cache_path(1000).name.startswith("seed01000-")


def test_cache_key_depends_on_every_simulated_tool(monkeypatch):
    """An instance cached while a plugin's tool was installed names that tool in its states, which a simulator
    without it refuses: such an entry must not be read once the plugin is gone (nor the other way round)."""
    import dataclasses

    import pasta.plugins

    real = pasta.plugins.get_plugins()
    task = get_task("push")
    without = task.key()

    class WithPincer:  # the installed plugins plus one tool of a plugin the push task does not use
        def __getattr__(self, name):
            return getattr(real, name)

        def simulated_tools(self):
            return [*real.simulated_tools(), dataclasses.replace(real.simulated_tools()[0], name="pincer")]

    monkeypatch.setattr(pasta.plugins, "get_plugins", WithPincer)
    assert task.key() != without


def test_check_push_records_missed_targets_and_disturbed_pieces():
    from types import SimpleNamespace

    from pasta.tasks.base import Generation

    rng = np.random.default_rng(0)
    before = np.concatenate([rng.random((50, 3)) * 0.05 + [0.3, 0.0, 0.3], rng.random((50, 3)) * 0.05 + [0.6, 0.0, 0.5]])
    after = before.copy()
    state = {"dough": after}
    sim = SimpleNamespace(observe=lambda: SimpleNamespace(dough=state["dough"]))
    gen = Generation(get_task("crs_twice"), sim, rng)
    gen.pieces = [np.arange(50), np.arange(50, 100)]
    c = after[:50].mean(0)
    gen.check_push(0, {"target_x": c[0] + 0.01, "target_z": c[2]}, before, tolerance=0.03, max_disturbance=0.01)
    assert gen.problems == []
    gen.check_push(0, {"target_x": c[0] + 0.05, "target_z": c[2]}, before, tolerance=0.03, max_disturbance=0.01)
    assert len(gen.problems) == 1 and "from its target" in gen.problems[0]
    state["dough"] = after + np.r_[np.zeros((50, 3)), np.tile([0.02, 0.0, 0.0], (50, 1))]
    gen.check_push(0, {"target_x": c[0], "target_z": c[2]}, before, tolerance=0.03, max_disturbance=0.01)
    assert len(gen.problems) == 2 and "moved piece 1" in gen.problems[1]


def test_generate_redraws_rejected_goals(monkeypatch):
    from types import SimpleNamespace

    from pasta.tasks.base import Generation

    task = get_task("push")
    calls = []

    def build(gen):
        calls.append(gen)
        if len(calls) < 3:
            gen.problems.append("missed")

    monkeypatch.setattr(task, "build", build)
    monkeypatch.setattr(Generation, "instance", lambda self, seed, attempt: SimpleNamespace(meta={}, attempt=attempt))
    inst = task.generate(1000, sim=object())
    assert inst.attempt == 2 and "problems" not in inst.meta and len(calls) == 3
    calls.clear()
    monkeypatch.setattr(task, "build", lambda gen: (calls.append(gen), gen.problems.append("missed")))
    inst = task.generate(1000, sim=object())  # every attempt rejected: the last one is kept, with its problems
    assert inst.attempt == task.config.max_retries and inst.meta["problems"] == ["missed"]
