"""`pasta train evaluate scene=VARIANT`: held-out configs drawn from a skill's scene variant, with
the variant's tools placed and its expert parameters, as `pasta demos scene=VARIANT` draws them."""

from types import SimpleNamespace

import numpy as np
import pytest

from pasta.core import ConfigError
from pasta.demos.generate import skill_config
from pasta.plugins import get_plugins
from pasta.train.evaluate import make_configs


class RecordingSim:
    """The calls make_configs makes of a simulator, recorded (no Taichi)."""

    def __init__(self) -> None:
        self.cfg = SimpleNamespace(n_particles=400)
        self.floor_y = 0.02
        self.tools: dict = {}
        self.x = None

    def reset(self, particles, seed=None):
        self.x, self.tools = np.asarray(particles), {}

    def step(self):
        pass

    def set_tool_pose(self, name, position, yaw=0.0):
        self.tools[name] = tuple(position)

    def observe(self):
        return SimpleNamespace(dough=self.x)

    def get_state(self):
        return SimpleNamespace(x=self.x.copy(), tools=dict(self.tools))


def test_board_scene_places_the_board_and_rests_the_dough_on_it():
    from pasta_skill_lift.tool import BOARD_POSE, BOARD_TOP

    roll = get_plugins().skills.create("roll", skill_config("roll", "board"))
    sim = RecordingSim()
    [cfg] = make_configs(roll, sim, 1, seed=2000, settle_steps=0, scene="board")
    assert cfg.state.tools == {"board": tuple(BOARD_POSE)}
    assert cfg.state.x[:, 1].min() >= BOARD_TOP - 1e-6  # on the board, not the floor
    [floor] = make_configs(get_plugins().skills.create("roll"), sim, 1, seed=2000, settle_steps=0)
    assert floor.state.tools == {} and floor.state.x[:, 1].min() < BOARD_TOP


def test_wide_scene_draws_targets_beyond_the_default_box():
    push = get_plugins().skills.create("push", skill_config("push", "wide"))
    assert push.config.target_x_max == pytest.approx(0.7)
    configs = make_configs(push, RecordingSim(), 12, seed=2000, settle_steps=0, scene="wide")
    default_max = get_plugins().skills.create("push").config.target_x_max
    assert max(c.params["target_x"] for c in configs) > default_max


def test_unknown_scene_names_the_known_ones():
    push = get_plugins().skills.create("push")
    with pytest.raises(ConfigError, match="wide"):
        make_configs(push, RecordingSim(), 1, seed=0, settle_steps=0, scene="wdie")


def test_default_skills_are_those_with_a_policy(tmp_path):
    """`pasta train evaluate` with no skills= scores the learned controller of every demo skill that has a policy
    (under models=, or shipped where the root borrows: an installed plugin without one is left out); naming a skill
    without one is an error that says how to train it."""
    from pasta.demos import demo_skills
    from pasta.train.evaluate import evaluate_config
    from pasta.weights import ROOT

    (tmp_path / "empty").mkdir()
    borrowing = evaluate_config({"models": str(tmp_path / "empty")})  # nothing of its own: the shipped policies serve
    assert borrowing.policy_dir("cut") == ROOT / "policy" / "cut"
    assert set(borrowing.skill_names()) == {name for name in demo_skills() if (ROOT / "policy" / name).is_dir()}
    own = tmp_path / "own"  # a root with its own VAE borrows nothing: only its cut policy
    for rel in ("vae", "policy/cut"):
        (own / rel).mkdir(parents=True)
        for name in ("model.safetensors", "model.json"):
            (own / rel / name).write_text("")
    assert evaluate_config({"models": str(own)}).skill_names() == ["cut"]
    assert evaluate_config({"models": str(own), "controllers": "heuristic"}).skill_names() == demo_skills()
    with pytest.raises(ConfigError, match="no trained policy of push in .*pasta train policy skill=push"):
        evaluate_config({"models": str(own), "skills": "push"})
