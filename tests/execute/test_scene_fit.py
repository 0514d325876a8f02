"""A skill is planned only where the scene allows it: needs declared by the skill, the scene by the task, by
``scene=`` or detected from the clouds (issue 45, item 1)."""

from __future__ import annotations

import numpy as np
import pytest

from pasta.cli import main
from pasta.core import Scene, SceneNeeds, SkillSpec
from pasta.core.errors import ConfigError, PluginValidationError
from pasta.execute.skillset import choose_skills
from pasta.plugins import get_plugins, hookimpl
from pasta.plugins.registry import discover
from pasta.tasks.scene import RAISED, detect_scene, floor_height, resolve_scene, scene_fit, scene_from_setting
from pasta.weights import ROOT

FLOOR = floor_height(64)


def test_needs_name_every_unmet_requirement():
    needs = SceneNeeds(static=("board",), surface=(0.04, 0.25), why="a raised surface")
    floor_only = Scene(surfaces=(FLOOR,))
    reasons = needs.unmet(floor_only, "spatula")
    assert reasons == ["needs the static tool board (a raised surface)",
                       "needs a raised surface 4-25 cm high, and the scene's surfaces are at 2.0 cm"]
    assert needs.unmet(Scene(static=("board",), surfaces=(FLOOR, 0.07)), "spatula") == []
    assert needs.unmet(Scene(static=("board",), surfaces=(0.07,), tools=("knife",)), "spatula") == [
        "its tool 'spatula' is not in the scene"]
    assert SceneNeeds().unmet(floor_only, "knife") == [] and SceneNeeds().describe() == ""
    assert "4-25 cm high" in needs.describe()


def test_needs_are_validated_when_a_skill_is_declared():
    with pytest.raises(PluginValidationError, match="tuple of tool names"):
        SceneNeeds(static="board")
    with pytest.raises(PluginValidationError, match="low <= high"):
        SceneNeeds(surface=(0.3, 0.1))
    with pytest.raises(PluginValidationError, match=r"needs must be a pasta\.core\.SceneNeeds"):
        SkillSpec("press", 1, 1, "knife", needs=("board",))


def test_resolved_scenes_add_the_floor_and_the_standing_tools_tops():
    board = get_plugins().tools.info("board").spec
    scene = resolve_scene(Scene(static=("board",), source="test"), FLOOR)
    assert scene.surfaces == (round(FLOOR, 4), round(board.stand_top, 4)) and scene.source == "test"
    assert "static board; surfaces at 2.0, 7.0 cm" in scene.describe()
    assert resolve_scene(Scene(), FLOOR).surfaces == (round(FLOOR, 4),)


@pytest.mark.parametrize(("value", "message"), [
    ("bord", "scene=bord: no such registered tool; did you mean 'board'"),
    ("knife", "'knife' is a movable tool, not a static one"),
])
def test_bad_scene_settings_name_the_static_tools(value, message):
    with pytest.raises(ConfigError, match=message):
        scene_from_setting(value, FLOOR)


def test_scene_settings():
    assert scene_from_setting("none", FLOOR).static == () and scene_from_setting("none", FLOOR).surfaces == (0.02,)
    assert scene_from_setting("board", FLOOR).static == ("board",)


def _slab(centre, size, n=600, seed=0):
    rng = np.random.default_rng(seed)
    return (np.asarray(centre) + (rng.random((n, 3)) - 0.5) * np.asarray(size)).astype(np.float32)


def test_detection_finds_a_surface_under_raised_dough_only():
    on_floor = _slab((0.6, FLOOR + 0.02, 0.5), (0.06, 0.04, 0.06))
    on_board = _slab((0.3, 0.07 + 0.01, 0.5), (0.08, 0.02, 0.08), seed=1)
    plain = detect_scene([on_floor, on_floor], FLOOR)
    assert plain.surfaces == (round(FLOOR, 4),) and "every piece on the floor" in plain.source
    raised = detect_scene([on_floor, np.concatenate([on_floor, on_board])], FLOOR)
    assert len(raised.surfaces) == 2 and abs(raised.surfaces[1] - 0.07) < 0.006 and raised.static == ()
    assert raised.surfaces[1] > FLOOR + RAISED
    lift = get_plugins().skills.info("lift").spec
    assert lift.needs.unmet(plain, lift.tool) and not lift.needs.unmet(raised, lift.tool)


def test_the_scene_leaves_out_skills_it_does_not_allow_and_says_why():
    floor_only = resolve_scene(Scene(source="task crs"), FLOOR)
    choice = choose_skills(None, ROOT, scene=floor_only)
    assert "lift" not in choice.names and "lift" in choice.unmet and "lift" not in choice.left_out
    assert {"cut", "push", "roll"} <= set(choice.names)
    note = choice.scene_note()
    assert note.startswith("scene: task crs: no static tools; surfaces at 2.0 cm; left out: lift (needs a raised")
    with pytest.raises(ConfigError, match=r"'lift': the scene \(task crs.*does not allow it: needs a raised"):
        choice.require(("push", "lift"), "skeleton=")
    with pytest.raises(ConfigError, match=r"skills= names skills the scene .* does not allow: 'lift'"):
        choose_skills("push,lift", ROOT, scene=floor_only)
    with_board = choose_skills(None, ROOT, scene=resolve_scene(Scene(static=("board",)), FLOOR))
    assert "lift" in with_board.names and not with_board.unmet
    assert choose_skills(None, ROOT).scene_note() is None  # no scene: no check


def test_every_task_plans_only_with_skills_its_scene_allows():
    """Sessions of every registered task: no chosen skill has unmet needs; the board tasks keep lift."""
    from pasta.execute.session import build_session

    plugins = get_plugins()
    for name in plugins.tasks.names():
        if name == "skill":
            continue  # one skill on its own demonstration scene (checked by its contract test)
        session = build_session(name)
        scene = session.skill_choice.scene
        assert scene is not None and scene.source == f"task {name}"
        assert not scene_fit([s.name for s in session.skills], scene, plugins.skills), name
        assert ("lift" in [s.name for s in session.skills]) == ("board" in scene.static), name
        record = session.describe()["scene"]  # what a result row records
        assert record["static"] == list(scene.static) and ("lift" in record["left_out"]) == ("board" not in scene.static)


class _ShelfSkillPlugin:
    @hookimpl
    def pasta_register_skills(self, register):
        register(spec=SkillSpec("stack", 1, 1, "knife", needs=SceneNeeds(static=("shelf",))),
                 factory="pasta.core:Skill")


def test_a_skill_needing_an_unregistered_static_tool_is_refused_at_load():
    plugins = discover(extra={"shelf": _ShelfSkillPlugin()})
    assert "stack" not in plugins.skills
    failure = next(f for f in plugins.failures if f.name == "stack")
    assert "needs the static tool shelf (SkillSpec.needs), which no plugin registers" in failure.message()


def test_pasta_plan_refuses_a_named_skill_the_scene_does_not_allow(tmp_path, capsys):
    np.save(tmp_path / "obs.npy", _slab((0.6, 0.04, 0.5), (0.06, 0.04, 0.06)))
    code = main(["plan", f"obs={tmp_path / 'obs.npy'}", f"goal={tmp_path / 'obs.npy'}", f"out={tmp_path / 'out'}",
                 "scene=none", "skills=push,lift"])
    assert code == 2
    err = capsys.readouterr().err
    assert "skills= names skills the scene (scene=none: no static tools; surfaces at 2.0 cm) does not allow: 'lift'" in err
    assert not (tmp_path / "out" / "plan.json").exists()
    assert main(["plan", f"obs={tmp_path / 'obs.npy'}", f"goal={tmp_path / 'obs.npy'}", f"out={tmp_path / 'o2'}",
                 "scene=shelf"]) == 2
    assert "scene=shelf: no such registered tool" in capsys.readouterr().err
