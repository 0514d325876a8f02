"""The results tables (README.md, docs/planning.md) are exactly what benchmarks/results_table.py
generates from docs/results, and every row they cite is a 20-config test-set summary with its per-episode rows."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _script():
    spec = importlib.util.spec_from_file_location("results_table", ROOT / "benchmarks" / "results_table.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_every_results_block_is_the_generated_one():
    rt = _script()
    assert set(rt.BLOCKS) == {"results", "plugin"} and rt.BLOCKS["results"][0] == "README.md"
    for block, (file, make) in rt.BLOCKS.items():
        assert rt.shown(block) == make(), f"{file}'s {block} table differs from `python benchmarks/results_table.py`: " \
                                          "run it with --write"


def _cited(rt):
    names = [f"{task}_pasta{suffix}" for task, _, _ in rt.TASKS for suffix in ("", "_learned")]
    names += [name for _, _, name, _, _ in rt.ABLATIONS] + rt.loop_names() + rt.plugin_names()
    return list(dict.fromkeys(names))


def test_every_cited_row_has_its_episodes():
    rt = _script()
    cited = [name for name in _cited(rt) if (rt.RESULTS / f"{name}.json").exists()]  # the others read "not run"
    assert {f"{task}_pasta" for task, _, _ in rt.TASKS} <= set(cited), "every task has its heuristic row"
    for name in cited:
        summary = json.loads((rt.RESULTS / f"{name}.json").read_text())
        rows = [json.loads(line) for line in (rt.RESULTS / f"{name}.jsonl").read_text().splitlines() if line.strip()]
        assert summary["split"] == "test" and summary["episodes"] == 20 == len(rows), name
        assert sorted(r["seed"] for r in rows) == list(range(1000, 1020)), name
        mean = sum(r["improvement"] for r in rows) / len(rows)
        assert abs(mean - summary["improvement_mean"]) < 1e-9, name


def test_every_trajopt_row_has_its_episodes():
    rt = _script()
    for name in rt.trajopt_names():
        if not (rt.RESULTS / f"{name}.json").exists():  # reads "not run"
            continue
        summary = json.loads((rt.RESULTS / f"{name}.json").read_text())
        rows = [json.loads(line) for line in (rt.RESULTS / f"{name}.jsonl").read_text().splitlines() if line.strip()]
        assert summary["split"] == "test" and summary["method"] == "trajopt", name
        assert summary["episodes"] == rt.TRAJOPT_CONFIGS == len(rows), name
        assert sorted(r["seed"] for r in rows) == list(range(1000, 1000 + rt.TRAJOPT_CONFIGS)), name
        assert all(len(r["trajopt"]["losses"]) == summary["config"]["trajopt"]["iterations"] for r in rows), name
        mean = sum(r["improvement"] for r in rows) / len(rows)
        assert abs(mean - summary["improvement_mean"]) < 1e-9, name


def test_rows_planned_with_a_skill_their_scene_leaves_out_are_marked():
    rt = _script()
    config = {"sim": {"n_grid": 64}}
    assert rt.outside_scene({"task": "crs", "skills": ["cut", "lift", "push"], "config": config}) == ["lift"]
    assert rt.outside_scene({"task": "lift_spread", "skills": ["lift", "roll"], "config": config}) == []
    summary = {"task": "crs", "skills": ["cut", "push", "roll"], "config": config, "improvement_mean": 0.9,
               "improvement_std": 0.1, "success_rate": 1.0, "method": "oracle"}
    assert rt._cell(summary) == "0.900 ± 0.100 / 100%"
    assert rt._cell({**summary, "skills": ["cut", "lift"]}).endswith(rt.OUTSIDE_SCENE)


def test_rows_made_with_other_weights_than_the_shipped_ones_are_marked():
    from pasta.io.checkpoint import weights_digest
    from pasta.weights import ROOT

    rt = _script()
    # paths as another machine recorded them: read under this checkout's shipped weights
    config = {"models": "", "encoder": {"weights": "/elsewhere/pasta/weights/vae"},
              "cost_model": {"weights": "/elsewhere/pasta/weights/cost"}, "sim": {"n_grid": 64}}
    current = {"encoder": weights_digest(ROOT / "vae"), "cost": weights_digest(ROOT / "cost"),
               "feasibility/cut": weights_digest(ROOT / "feasibility" / "cut")}
    row = {"task": "crs", "method": "pasta", "skills": ["cut"], "config": config, "weights": current}
    assert rt.other_weights(row) == [] and rt.stale(row) == []
    assert rt.other_weights({**row, "weights": {**current, "cost": "0" * 16}}) == ["cost"]
    assert rt.other_weights({**row, "weights": None}) == ["unrecorded"]
    assert rt.stale({**row, "weights": None, "skills": ["lift"]}) == ["scene", "weights"]
    # a policy counts only where the row executed its skill
    changed = {**current, "policy/roll": "0" * 16}
    assert rt.other_weights({**row, "weights": changed}) == ["policy/roll"]  # not known what was executed
    assert rt.other_weights({**row, "weights": changed, "executed_skills": ["cut", "roll"]}) == ["policy/roll"]
    assert rt.other_weights({**row, "weights": changed, "executed_skills": ["cut"]}) == []


def test_summaries_know_the_skills_their_episodes_executed(tmp_path):
    rt = _script()
    (tmp_path / "t_pasta.json").write_text(json.dumps({"task": "t"}))
    assert "executed_skills" not in rt._summary(tmp_path, "t_pasta")
    episodes = [{"seed": 0, "steps": [{"skill": "push"}, {"skill": "cut"}]}, {"seed": 1, "steps": []},
                {"seed": 2, "steps": [{"skill": "push"}]}]
    (tmp_path / "t_pasta.jsonl").write_text("".join(json.dumps(e) + "\n" for e in episodes))
    assert rt._summary(tmp_path, "t_pasta")["executed_skills"] == ["cut", "push"]
    assert rt._summary(tmp_path, "missing") is None


def test_no_episode_of_a_current_row_plans_a_skill_its_scene_leaves_out():
    """Every cited row run with the scene check (not marked †): no episode's plan uses a skill the scene leaves out."""
    from pasta.tasks import get_task
    from pasta.tasks.scene import floor_height, resolve_scene, scene_fit

    from pasta.plugins import get_plugins

    rt = _script()
    registered = get_plugins().skills
    checked = 0
    for name in _cited(rt):
        if not (rt.RESULTS / f"{name}.json").exists():
            continue
        summary = json.loads((rt.RESULTS / f"{name}.json").read_text())
        if rt.outside_scene(summary) or summary.get("method") in rt.NOT_PLANNED:
            continue
        scene = resolve_scene(get_task(summary["task"]).scene(), floor_height(64))
        for line in (rt.RESULTS / f"{name}.jsonl").read_text().splitlines():
            row = json.loads(line) if line.strip() else None
            if row:
                known = [skill for skill in row["skeleton"] if skill in registered]  # a plugin's: where installed
                assert not scene_fit(known, scene), (name, row["seed"], row["skeleton"])
                checked += 1
    assert checked >= 40  # at least the re-run crs and cut_rearrange rows


def test_the_readme_stays_a_users_document_of_at_most_250_lines():
    lines = (ROOT / "README.md").read_text().splitlines()
    assert len(lines) <= 250, f"README.md has {len(lines)} lines: history goes to CHANGELOG.md, details to docs/"


def test_installing_the_example_plugin_costs_no_row_more_than_one_success():
    """docs/planning.md: every task re-run with the example third-party skill a candidate (its trained root): no row
    loses more than one of its 20 successes, and its skill set really held the plugin's skill."""
    rt = _script()
    skill = rt.PLUGIN[1]
    compared = 0
    for task, _, _ in rt.TASKS:
        for learned in (False, True):
            name = rt.plugin_name(task, learned=learned)
            if not (rt.RESULTS / f"{name}.json").exists():
                continue
            with_plugin = json.loads((rt.RESULTS / f"{name}.json").read_text())
            shipped = json.loads((rt.RESULTS / f"{task}_pasta{'_learned' if learned else ''}.json").read_text())
            assert skill in with_plugin["skills"], name
            lost = round(20 * (shipped["success_rate"] - with_plugin["success_rate"]))
            assert lost <= 1, f"{name}: {lost} successes fewer than without the plugin"
            compared += 1
    assert compared >= len(rt.TASKS)  # at least every task's heuristic row
