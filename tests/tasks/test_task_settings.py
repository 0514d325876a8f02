"""Task settings from the command line (``task.<setting>=``) and crs_distractors at any count."""

from __future__ import annotations

import numpy as np
import pytest

from pasta.cli import main
from pasta.commands.eval import result_path
from pasta.core.errors import ConfigError
from pasta.tasks import get_task
from pasta_tasks_crs.tasks import DISTRACTOR_GAP, MAX_DISTRACTORS, distractor_boxes


def test_task_settings_are_a_section_of_the_run_config():
    from pasta.config import load_config, section

    cfg = load_config(["task=crs_distractors", "task.distractors=4", "task.threshold=0.8"])
    assert cfg.task.name == "crs_distractors" and section(cfg, "task").distractors == 4
    with pytest.raises(ConfigError, match="did you mean 'task.distractors'"):
        load_config(["task=crs_distractors", "task.distractor=4"])


def test_string_settings_are_typed_and_checked():
    task = get_task("crs_distractors", distractors="4", threshold="0.9")
    assert task.config.distractors == 4 and task.threshold == pytest.approx(0.9)
    assert get_task("crs_distractors").config.distractors == 2  # the test set of the paper's setting
    assert task.key() != get_task("crs_distractors").key()  # other instances, another cache entry
    with pytest.raises(ConfigError, match="did you mean 'distractors'"):
        get_task("crs_distractors", distractor="4")
    with pytest.raises(ConfigError, match="distractors must be in 0..6"):
        get_task("crs_distractors", distractors="7")
    with pytest.raises(ConfigError, match="distractors"):
        get_task("crs_distractors", distractors="many")


@pytest.mark.parametrize("num", range(MAX_DISTRACTORS + 1))
def test_distractors_alternate_walls_and_keep_apart(num):
    for seed in range(50):
        boxes = distractor_boxes(np.random.default_rng(seed), 0.01, num)
        assert len(boxes) == num
        walls = [0 if z < 0.5 else 1 for (_, _, z), _ in boxes]
        assert all(a != b for a, b in zip(walls, walls[1:]))  # front, back, front, ... (or the reverse)
        for (x, y, z), (side, _, _) in boxes:
            assert 0.2 <= x <= 0.8 and (0.1 <= z <= 0.18 or 0.82 <= z <= 0.9)
            assert y == pytest.approx(0.01 + side / 2)  # resting on the floor
        for wall in (0, 1):
            mine = [(x, s) for ((x, _, _), (s, _, _)), w in zip(boxes, walls) if w == wall]
            for a in range(len(mine)):
                for b in range(a + 1, len(mine)):
                    gap = abs(mine[a][0] - mine[b][0]) - (mine[a][1] + mine[b][1]) / 2
                    assert gap >= DISTRACTOR_GAP - 1e-12
        # more distractors draw the same first two: the default 2-distractor scenes do not change
        if num >= 2:
            assert distractor_boxes(np.random.default_rng(seed), 0.01, 2) == boxes[:2]
    with pytest.raises(ValueError, match="at most 6"):
        distractor_boxes(np.random.default_rng(0), 0.0, MAX_DISTRACTORS + 1)


def test_result_file_names_the_settings(tmp_path):
    from pasta.config import load_config

    def name(*items, split="test"):
        return result_path(tmp_path, load_config(["task=crs_distractors", *items]), list(items), split).name

    assert name() == "crs_distractors_pasta.jsonl"
    assert name("task.distractors=4") == "crs_distractors_pasta_distractors4.jsonl"
    assert name("execute.controller=learned", "task.distractors=1", split="val") == \
        "crs_distractors_pasta_distractors1_learned_val.jsonl"
    assert name("skills=cut,push,roll", "horizon=4", "threads=1") == "crs_distractors_pasta_horizon4_skills-cut-push-roll.jsonl"
    # other weights give other results: the root is named by its folder
    assert name("models=pasta/weights/ablations/no_hard_negatives") == "crs_distractors_pasta_models-no-hard-negatives.jsonl"


def test_bad_settings_fail_before_any_work(tmp_path, capsys):
    assert main(["eval", "task=crs_distractors", "task.distractor=4", "num=1", f"out={tmp_path}"]) == 2
    assert "did you mean 'task.distractors'" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())  # nothing written
    assert main(["run", "task=crs_distractors", "task.distractors=9"]) == 2
    assert "distractors must be in 0..6" in capsys.readouterr().err
    assert main(["eval", "task=crs", "method=oracle", "task.distractors=1", "num=1"]) == 2  # crs has no such setting
    assert "unknown config key 'task.distractors'" in capsys.readouterr().err


@pytest.mark.sim
def test_four_distractors_stay_put_in_the_goal(tmp_path, monkeypatch):
    from pasta.core.decompose import decompose_labels
    from pasta.core.matching import unchanged_pairs
    from pasta.core.metrics import sample_points

    monkeypatch.setenv("PASTA_TASK_CACHE", str(tmp_path))
    task = get_task("crs_distractors", distractors=4, n_particles=2000)
    inst = task.instance(1000)
    assert len(inst.pieces) == 5
    rng = np.random.default_rng(0)
    lo, lg = decompose_labels(inst.init_points), decompose_labels(inst.goal)
    obs = [inst.init_points[lo == e] for e in range(lo.max() + 1)]
    goal = [inst.goal[lg == e] for e in range(lg.max() + 1)]
    assert len(obs) == 5 and len(goal) == 6  # the dough and 4 cubes; the dough cut in two
    pairs = unchanged_pairs(np.stack([sample_points(p, 300, rng) for p in obs]),
                            np.stack([sample_points(p, 300, rng) for p in goal]))
    assert len(pairs) == 4  # every cube sits where it started
