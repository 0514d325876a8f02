"""Demonstration scenes come from the skill plugins: hooks, variants and their validation (no simulator)."""

import numpy as np
import pytest

from pasta.core import Skill, SkillSpec
from pasta.core.errors import ConfigError, InputError, MissingComponentError
from pasta.demos import demo_skills, scene_boxes, scene_particles, variants
from pasta.demos.generate import DemoConfig, skill_config, validate
from pasta.plugins import get_plugins


def test_builtin_skills_make_demonstrations_and_base_skill_does_not():
    assert {"cut", "push", "roll"} <= set(demo_skills())  # other installed skills may make demos too

    class Bare(Skill):
        spec = SkillSpec("bare", 1, 1, "pusher")

    assert not Bare.has_expert() and Bare.missing_demo_hooks() == list(Skill.DEMO_HOOKS)
    with pytest.raises(MissingComponentError, match="skill 'bare' has no demonstration scene"):
        Bare().demo_scene(np.random.default_rng(0), 0.0)
    with pytest.raises(MissingComponentError, match="skill 'bare' has no scripted expert"):
        Bare().expert_approach_pose(np.zeros((4, 3)), {})


def sampled_boxes(skill: str, variant: str, n: int = 200) -> list:
    """``(centre, size)`` of the first box of ``n`` scenes of ``skill``'s ``variant`` (one seeded stream)."""
    sk, rng = get_plugins().skills.create(skill), np.random.default_rng(0)
    return [scene_boxes(sk, rng, 0.0, variant)[0] for _ in range(n)]


def test_wide_push_scene_covers_the_right_of_the_workspace():
    boxes = sampled_boxes("push", "wide")
    xs = np.array([c[0] for c, _ in boxes])
    lengths = np.array([s[0] for _, s in boxes])
    assert xs.max() > 0.75 and lengths.max() > 0.2  # default push pieces start at x <= 0.7, length <= 0.12
    assert np.all(xs + lengths / 2 <= 0.93 + 1e-9)
    # the variant also widens the expert's target box (declared by the plugin, applied by pasta.demos)
    assert skill_config("push", "wide").target_x_max == 0.7 and skill_config("push").target_x_max == 0.32


def test_roll_pieces_scene_spans_the_pushed_pieces_of_the_crs_tasks():
    boxes = sampled_boxes("roll", "pieces")
    depth = np.array([s[2] for _, s in boxes])
    z = np.array([c[2] for c, _ in boxes])
    assert depth.max() > 0.12 and depth.min() >= 0.07  # the default scene's pieces are at most 0.08 deep
    assert np.all(z - depth / 2 >= 0.2 - 1e-9) and np.all(z + depth / 2 <= 0.8 + 1e-9)
    assert z.min() < 0.3 and z.max() > 0.7  # beyond the default scene's z 0.3-0.7
    assert "pieces" in variants(get_plugins().skills.load("roll"))


def test_long_cut_scene_covers_the_first_cut_of_crs_twice():
    boxes = sampled_boxes("cut", "long")
    lengths = np.array([s[0] for _, s in boxes])
    assert lengths.min() >= 0.3 and lengths.max() <= 0.35  # the default scene: 0.2-0.35
    cfg = skill_config("cut", "long")
    assert (cfg.offset_max, cfg.shift_max) == (0.25, 0.12) and skill_config("cut").offset_max == 0.2
    # the expert's cuts reach crs_twice's first cut (0.20-0.24 from the end, travel 0.10-0.12)
    cut = type(get_plugins().skills.create("cut"))(cfg)
    rng = np.random.default_rng(0)
    piece = np.random.default_rng(1).uniform([0.55, 0.0, 0.45], [0.9, 0.08, 0.52], (2000, 3))
    left = float(np.percentile(piece[:, 0], 0.5))
    params = [cut.sample_expert_params(piece, rng) for _ in range(300)]
    offsets = np.array([p["cut_x"] - left for p in params])
    shifts = -np.array([p["shift"] for p in params])
    assert offsets.max() > 0.23 and offsets.max() <= 0.25 + 1e-9 and shifts.max() > 0.11


def test_scene_variants_are_checked(tmp_path):
    cut = get_plugins().skills.create("cut")
    assert variants(type(cut)) == ["default", "long"] and variants(get_plugins().skills.load("push")) == ["default", "wide", "nudge"]
    with pytest.raises(ConfigError, match="skill 'cut' has no demonstration scene 'wide'; its scenes: default, long"):
        scene_boxes(cut, np.random.default_rng(0), 0.0, "wide")
    with pytest.raises(ConfigError, match="scene"):
        validate(DemoConfig(skill="cut", out=str(tmp_path), scene="wide"))
    with pytest.raises(ConfigError, match="its scenes: default, wide"):
        validate(DemoConfig(skill="push", out=str(tmp_path), scene="wider"))


def test_scene_boxes_must_match_the_skill_cardinality():
    class TwoIn(Skill):
        spec = SkillSpec("two_in", 2, 1, "pusher")

        def demo_scene(self, rng, floor_y, variant="default"):
            return [((0.5, floor_y + 0.04, 0.5), (0.1, 0.08, 0.08))]

    with pytest.raises(InputError, match="consumes 2 piece\\(s\\) but its demo_scene returned 1 box"):
        scene_boxes(TwoIn(), np.random.default_rng(0), 0.0)


def test_scene_particles_split_by_volume_and_one_box_is_box_particles():
    from pasta.sim import box_particles

    box = ((0.5, 0.06, 0.5), (0.1, 0.08, 0.07))
    one, owner = scene_particles([box], 500, np.random.default_rng(3))
    assert np.array_equal(one, box_particles(*box, 500, np.random.default_rng(3))) and (owner == 0).all()
    big = ((0.3, 0.06, 0.5), (0.2, 0.08, 0.07))
    pts, owner = scene_particles([box, big], 900, np.random.default_rng(3))
    assert pts.shape == (900, 3) and pts.dtype == np.float32
    assert np.bincount(owner).tolist() == [300, 600]
    assert np.all(np.abs(pts[owner == 1, 0] - 0.3) <= 0.1 + 1e-6)


def test_a_demonstration_within_at_goal_is_kept_when_its_skill_calls_the_piece_unfinished():
    """check_changed refuses a 1 -> 1 demonstration that moved its piece less than the skill's at_goal, unless the
    skill's own measure says the piece was not at that goal (a roll of a cube into a sheet)."""
    from pasta.core import InputError
    from pasta.demos.generate import check_changed

    class _Skill:
        name, n_in, n_out, at_goal = "flatten", 1, 1, 1e-3

        def __init__(self, unfinished):
            self._unfinished = unfinished

        def unfinished(self, piece, goal):
            return self._unfinished

    before = np.random.default_rng(0).uniform(0, 0.05, (600, 3))
    after = before + (0.01, 0, 0)  # Chamfer ~2e-4
    with pytest.raises(InputError, match="below 0.001 \\(its at_goal\\)"):
        check_changed(_Skill(False), before, after, 0)
    assert 0 < check_changed(_Skill(True), before, after, 0) < 1e-3
