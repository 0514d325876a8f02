"""Demonstrations and training for a skill that only a third-party plugin knows: 'merge' (2 -> 1, pushes one
small box into another with the built-in pusher) and 'nudge' (1 -> 1), written against the public API and
installed as an entry point of a throwaway distribution (a *.dist-info on sys.path, no pip)."""

from __future__ import annotations

import json
import sys
import textwrap
from types import SimpleNamespace

import numpy as np
import pytest
import torch

from pasta.cli import main
from pasta.core import ToolPose
from pasta.core.errors import ConfigError

PLUGIN = '''
"""Two skills made of public pasta API only: each demonstration pushes the right-most dough piece to the left."""
import numpy as np

from pasta.core import Controller, Skill, SkillSpec, ToolPose
from pasta.plugins import hookimpl

HEIGHT = 0.06
PUSHER_HALF_X, PUSHER_HALF_Y = 0.015, 0.05  # the built-in pusher's paddle (thin along x)
STEP = 0.01  # the pusher's travel per env step at action 1


class PushLeft(Controller):
    """The pusher moves left at full speed for ``steps`` env steps."""

    def __init__(self, steps):
        self.steps, self.taken = steps, 0

    def act(self, obs):
        if self.taken >= self.steps:
            return np.zeros(4, np.float32), True
        self.taken += 1
        return np.array([-1.0, 0.0, 0.0, 0.0], np.float32), False


class PushLeftSkill(Skill):
    max_steps = 40

    def expert_approach_pose(self, piece, params, scene=None):
        moved = piece[piece[:, 0] > params["split_x"]]  # the piece the pusher moves
        y = float(np.percentile(moved[:, 1], 1)) - 0.005 + PUSHER_HALF_Y
        return ToolPose((float(moved[:, 0].max()) + PUSHER_HALF_X + 0.008, y, float(moved[:, 2].mean())), 0.0)

    def expert(self, params):
        return PushLeft(int(np.ceil(params["travel"] / STEP)))


class MergeSkill(PushLeftSkill):
    spec = SkillSpec("merge", n_in=2, n_out=1, tool="pusher", description="push one piece into another")
    training_defaults = {"feasibility": {"stride": 2}}

    def demo_scene(self, rng, floor_y, variant="default"):
        z, left, gap = rng.uniform(0.4, 0.6), rng.uniform(0.35, 0.45), rng.uniform(0.06, 0.08)
        size = (0.05, HEIGHT, 0.06)
        return [((left, floor_y + HEIGHT / 2, z), size), ((left + 0.05 + gap, floor_y + HEIGHT / 2, z), size)]

    def sample_expert_params(self, piece, rng):
        x = np.sort(piece[:, 0])
        i = int(np.argmax(np.diff(x)))  # the gap between the two boxes
        return {"split_x": float(x[i] + x[i + 1]) / 2, "travel": float(x[i + 1] - x[i])}


class NudgeSkill(PushLeftSkill):
    spec = SkillSpec("nudge", n_in=1, n_out=1, tool="pusher", description="push a piece a little to the left")

    def demo_scene(self, rng, floor_y, variant="default"):
        return [((rng.uniform(0.5, 0.6), floor_y + HEIGHT / 2, rng.uniform(0.4, 0.6)), (0.06, HEIGHT, 0.06))]

    def sample_expert_params(self, piece, rng):
        return {"split_x": float(piece[:, 0].min()) - 1.0, "travel": float(rng.uniform(0.04, 0.08))}


class StillSkill(NudgeSkill):
    spec = SkillSpec("still", n_in=1, n_out=1, tool="pusher", description="an expert that leaves its piece as it is")

    def sample_expert_params(self, piece, rng):
        return {"split_x": float(piece[:, 0].min()) - 1.0, "travel": 0.0}


class SlideSkill(Skill):
    """No scripted expert: a target (the piece slid 4-8 cm left) for trajectory optimisation to reach."""

    spec = SkillSpec("slide", n_in=1, n_out=1, tool="pusher", description="slide a piece to the left")

    def demo_scene(self, rng, floor_y, variant="default"):
        return [((rng.uniform(0.5, 0.6), floor_y + HEIGHT / 2, rng.uniform(0.4, 0.6)), (0.06, HEIGHT, 0.06))]

    def demo_target(self, dough, rng, variant="default"):
        return dough - np.array([rng.uniform(0.04, 0.08), 0.0, 0.0], np.float32)

    def approach_pose(self, piece, goal, scene=None):
        y = float(np.percentile(piece[:, 1], 1)) - 0.005 + PUSHER_HALF_Y
        return ToolPose((float(piece[:, 0].max()) + PUSHER_HALF_X + 0.008, y, float(piece[:, 2].mean())), 0.0)

    def park_pose(self):
        return ToolPose((0.95, 0.3, 0.95), 0.0)


class LazySkill(Skill):
    spec = SkillSpec("lazy", n_in=1, n_out=1, tool="pusher", description="no expert, no demonstrations")


@hookimpl
def pasta_register_skills(register):
    register(spec=MergeSkill.spec, factory="merge_plugin:MergeSkill")
    register(spec=NudgeSkill.spec, factory="merge_plugin:NudgeSkill")
    register(spec=StillSkill.spec, factory="merge_plugin:StillSkill")
    register(spec=LazySkill.spec, factory="merge_plugin:LazySkill")
    register(spec=SlideSkill.spec, factory="merge_plugin:SlideSkill")
'''

TINY_VAE = {"epochs": "1", "width": "16", "fold_hidden": "16", "input_points": "64", "target_points": "64",
            "emd_points": "16", "num_points": "128", "stride": "2", "batch_size": "8"}
TINY_FEASIBILITY = {"epochs": "1", "hidden": "16", "num_points": "128", "match_points": "64", "hard_per_positive": "2"}
TINY_POLICY = {"epochs": "1", "steps_per_epoch": "2", "val_batches": "1", "batch_size": "4", "dough_points": "32",
               "tool_points": "8", "goal_points": "32"}


@pytest.fixture
def merge_plugin(tmp_path, monkeypatch, fresh_plugins):
    """The plugin installed as the entry point 'merge' of distribution merge-pkg; the plugin cache rescanned
    (and rescanned again without it afterwards, by ``fresh_plugins``)."""
    root = tmp_path / "site"
    info = root / "merge_pkg-0.1.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: merge-pkg\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text("[pasta.plugins]\nmerge = merge_plugin\n")
    (root / "merge_plugin.py").write_text(textwrap.dedent(PLUGIN))
    monkeypatch.syspath_prepend(str(root))
    yield fresh_plugins()
    sys.modules.pop("merge_plugin", None)


def test_plugin_skills_with_an_expert_are_the_demo_skills(merge_plugin, tmp_path, capsys):
    from pasta.demos import DemoConfig, demo_skills, validate
    from pasta.pipeline import PipelineConfig, plan

    # every registered skill but lazy (it has no expert), whichever other plugins are installed
    expected = [name for name in merge_plugin.skills.names() if name != "lazy"]
    assert demo_skills() == expected and {"cut", "merge", "nudge", "push", "roll"} <= set(expected)
    with pytest.raises(ConfigError, match=r"skill 'lazy' cannot make demonstrations: its plugin defines neither a "
                                          r"scripted expert \(missing demo_scene, sample_expert_params, "
                                          r"expert_approach_pose, expert\) nor a target for trajectory optimisation "
                                          r"\(missing demo_scene, demo_target\)"):
        validate(DemoConfig(skill="lazy", out=str(tmp_path)))
    assert main(["demos", "skill=lazy", f"out={tmp_path}"]) == 2
    assert f"skills with demonstrations: {', '.join(expected)}" in capsys.readouterr().err
    # the pipeline's default skill set is every skill that can make demonstrations, with their own settings
    units = {u.name: u for u in plan(PipelineConfig(stages="demos,feasibility"), {})}
    assert "demos/merge" in units and "demos/lazy" not in units
    assert units["feasibility/merge"].configs[1].stride == 2 and units["feasibility/nudge"].configs[1].stride == 1
    with pytest.raises(ConfigError, match="lazy"):
        plan(PipelineConfig(stages="demos", skills="merge,lazy"), {})


@pytest.mark.sim
def test_two_to_one_and_one_to_one_plugin_skills_demos_and_training(merge_plugin, tmp_path):
    """2 demonstrations of each, then a tiny VAE, 1 epoch of feasibility and of policy training, through
    ``pasta pipeline`` with the plugin's skills (what `pasta demos` / `pasta train` run one by one)."""
    from pasta.core.decompose import decompose
    from pasta.nn.loading import load_feasibility
    from pasta.demos.data import load_demos
    from pasta.pipeline import run_pipeline

    data, out = tmp_path / "demos", tmp_path / "models"
    stage_args = [f"{stage}.{k}={v}" for stage, values in (("vae", TINY_VAE), ("feasibility", TINY_FEASIBILITY),
                                                           ("policy", TINY_POLICY)) for k, v in values.items()]
    results = run_pipeline([f"data={data}", f"out={out}", "stages=demos,vae,feasibility,policy", "skills=merge,nudge",
                            "num_demos=2", "workers=0", "progress=false", "demos.n_particles=2000",
                            "demos.obs_points=400", *stage_args], echo=lambda _: None)
    assert {r.name: r.status for r in results} == dict.fromkeys(("demos/merge", "demos/nudge", "vae", "feasibility/merge", "feasibility/nudge", "policy/merge", "policy/nudge"), "ran")

    manifest = json.loads((data / "manifest.json").read_text())
    assert manifest["counts"] == {"merge": 2, "nudge": 2} and manifest["skills"]["merge"]["tool"] == "pusher"
    for demo in load_demos(data, ["merge"]):
        assert demo.dough.shape[1:] == (400, 3) and demo.action.shape[1] == 4 and len(demo.params["scenes"]) == 2
        # the expert pushed one box into the other: two pieces before, one after
        assert len(decompose(demo.dough[0], num_points=128)) == 2 and len(decompose(demo.after, num_points=128)) == 1
    for demo in load_demos(data, ["nudge"]):
        assert "scene" in demo.params and len(decompose(demo.after, num_points=128)) == 1
        assert demo.after[:, 0].mean() < demo.dough[0][:, 0].mean() - 0.02  # pushed left

    for name, (n_in, n_out) in (("merge", (2, 1)), ("nudge", (1, 1))):
        metrics = json.loads((out / "feasibility" / name / "metrics.json").read_text())
        assert metrics["train_positives"] > 0 and 0.0 <= metrics["heldout_auc_hard"] <= 1.0
        skill = merge_plugin.skills.create(name)
        skill.attach_feasibility(load_feasibility(out / "feasibility" / name, skill=name, n_in=n_in, n_out=n_out))
        f = skill.feasibility(torch.zeros(3, n_in, 5), torch.zeros(3, n_out, 5))
        assert f.shape == (3,) and bool(((f >= 0) & (f <= 1)).all())
        policy = json.loads((out / "policy" / name / "metrics.json").read_text())
        assert policy["skill"] == name and policy["train_demos"] == 1


@pytest.mark.sim
def test_demonstrations_that_leave_the_piece_at_its_start_are_refused_with_the_threshold(merge_plugin, tmp_path, capsys):
    """A step that changes its piece less than pasta's "this piece is its goal" distance is never planned or
    run: its demonstrations are refused, naming the distance and the threshold (issue 40)."""
    assert main(["demos", "skill=still", "num=1", f"out={tmp_path}", "workers=0", "n_particles=1500",
                 "obs_points=300"]) == 1
    err = capsys.readouterr().err
    assert "demo 0 (seed=0 skill=still index=0): raised InputError: skill 'still' demo 0: its expert changed the " \
           "dough by a Chamfer distance of" in err
    assert "below 0.0005 (perception.unchanged_threshold)" in err and "Traceback" in err
    assert not list((tmp_path / "still").glob("demo_*.npz"))


def test_expert_choice_is_checked(merge_plugin, tmp_path):
    from pasta.demos import DemoConfig, validate

    validate(DemoConfig(skill="slide", out=str(tmp_path)))  # no scripted expert: trajectory optimisation
    with pytest.raises(ConfigError, match="expert=scripted: skill 'slide' has no scripted expert"):
        validate(DemoConfig(skill="slide", out=str(tmp_path), expert="scripted"))
    with pytest.raises(ConfigError, match="expert=trajopt: skill 'nudge' defines no demo_target"):
        validate(DemoConfig(skill="nudge", out=str(tmp_path), expert="trajopt"))
    with pytest.raises(ConfigError, match="expert"):
        validate(DemoConfig(skill="nudge", out=str(tmp_path), expert="gbto"))


@pytest.mark.sim
def test_a_skill_without_an_expert_gets_demonstrations_by_trajectory_optimisation(merge_plugin, tmp_path):
    """`pasta demos` for a skill with a demo target and no scripted expert: GBTO finds the actions, and the demo
    is recorded like an expert's (the file format every trainer reads), the optimisation in its params."""
    from pasta.demos.data import load_demos

    assert main(["demos", "skill=slide", "num=1", f"out={tmp_path}", "workers=0", "n_particles=1500",
                 "obs_points=300", "trajopt_iterations=6", "trajopt_steps=10"]) == 0
    (demo,) = load_demos(tmp_path, ["slide"])
    assert demo.params["expert"] == "trajopt" and len(demo.params["losses"]) == 6
    assert demo.action.shape == (10, 4) and demo.dough.shape == (11, 300, 3)
    best = demo.params["best_iteration"]
    assert best > 0 and demo.params["losses"][best] < demo.params["losses"][0]  # the optimiser lowered the loss
    assert demo.after[:, 0].mean() < demo.dough[0][:, 0].mean() - 0.005  # and slid the piece left


@pytest.mark.sim
@pytest.mark.slow
def test_a_skill_without_an_expert_gets_task_goals_by_trajectory_optimisation(merge_plugin):
    """`task=skill task.skill=slide`: the goal is made by GBTO (20 iterations of 50 steps at 5,000 particles:
    minutes on 2 cores, hence the slow tier), recorded as the step's params, and the piece ends left of where it
    started, as its target asks."""
    task = merge_plugin.tasks.load("skill")(merge_plugin.tasks.default_config("skill").__class__(skill="slide"), None)
    inst = task.generate(2000)
    (step,) = inst.steps
    assert step.skill == "slide" and step.params["expert"] == "trajopt" and step.steps == 50
    assert step.params["losses"][step.params["best_iteration"]] < step.params["losses"][0]
    assert inst.goal[:, 0].mean() < inst.init_points[:, 0].mean() - 0.01


class StillSim:
    """The calls single-skill evaluation makes of a simulator before any step runs (no Taichi)."""

    cfg = SimpleNamespace(n_particles=300)
    floor_y = 0.02

    def reset(self, particles, seed=None):
        self.x = np.asarray(particles)

    def set_tool_pose(self, name, position, yaw=0.0):
        pass

    def observe(self):
        return SimpleNamespace(dough=self.x)

    def get_state(self):
        return self.x.copy()


def test_single_skill_evaluation_makes_the_goal_of_a_skill_without_an_expert_by_optimisation_once(merge_plugin,
                                                                                                  monkeypatch):
    """`pasta train evaluate skills=slide`: each held-out config optimises its goal once, from its own seed, and
    every expert run replays those actions in full; the skill has no heuristic controller to score."""
    import pasta.tasks.step as step
    from pasta.train.evaluate import make_configs

    seeds = []

    def optimise(sim, skill, dough, piece, rng, **kw):
        seeds.append(int(rng.integers(2**31)))
        return {"expert": "trajopt"}, ToolPose((0.5, 0.1, 0.5), 0.0), step.Replay(np.full((7, 4), -0.5))

    monkeypatch.setattr(step, "gbto_expert", optimise)
    slide, sim = merge_plugin.skills.create("slide"), StillSim()
    configs = make_configs(slide, sim, 2, seed=1000, settle_steps=0)
    assert [c.params for c in configs] == [{}, {}] and configs[0].goal_seed != configs[1].goal_seed
    first, again = configs[0].expert(sim, slide), configs[0].expert(sim, slide)
    assert len(seeds) == 1 and first[2] == again[2] == 7 and first[1] is not again[1]
    assert first[0] == again[0] and np.array_equal(first[1].actions, again[1].actions)
    assert make_configs(slide, sim, 1, seed=1000, settle_steps=0)[0].goal_seed == configs[0].goal_seed
    # a skill with a scripted expert draws its parameters as before and runs its expert to the skill's limit
    nudge = merge_plugin.skills.create("nudge")
    (cfg,) = make_configs(nudge, sim, 1, seed=1000, settle_steps=0)
    assert set(cfg.params) == {"split_x", "travel"} and cfg.goal_seed == 0 and cfg.expert(sim, nudge)[2] is None
    assert not type(slide).has_controller() and not type(nudge).has_controller()
    assert type(merge_plugin.skills.create("push")).has_controller()


def test_a_skill_sets_its_own_trajectory_optimisation_budget(merge_plugin, monkeypatch):
    """`training_defaults["demos"]` of a plugin sets how long GBTO optimises for it: in `pasta demos` (0 keeps the
    skill's own), the ground-truth steps of tasks and evaluation alike."""
    from pasta.tasks.step import GBTO_ITERATIONS, GBTO_STEPS, gbto_budget

    slide = type(merge_plugin.skills.create("slide"))
    assert gbto_budget(slide) == (GBTO_ITERATIONS, GBTO_STEPS)
    monkeypatch.setattr(slide, "training_defaults", {"demos": {"trajopt_steps": 12}})
    assert gbto_budget(slide) == (GBTO_ITERATIONS, 12)


def test_the_skill_contract_checks_a_demonstration_target(merge_plugin, monkeypatch):
    """`check_skill` (every SkillContract's test_conforms) refuses a demo_target that returns the scene itself, a
    non-finite cloud or a new random draw each call, and passes the slide skill's."""
    from pasta.testing import PluginConformanceError, check_skill

    slide = merge_plugin.skills.create("slide")
    check_skill(slide)
    cls = type(slide)
    for bad, message in ((lambda self, dough, rng, variant="default": dough, "the scene itself"),
                         (lambda self, dough, rng, variant="default": dough * np.nan, "non-finite"),
                         (lambda self, dough, rng, variant="default": dough + np.random.default_rng().uniform(0, 0.1),
                          "every random number from its rng")):
        monkeypatch.setattr(cls, "demo_target", bad)
        with pytest.raises(PluginConformanceError, match=message):
            check_skill(slide)
