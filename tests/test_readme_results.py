"""The README's results tables are exactly what benchmarks/results_table.py generates from docs/results, and every
row it cites is a 20-config test-set summary with its per-episode rows beside it."""

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


def test_readme_table_is_the_generated_one():
    rt = _script()
    readme = (ROOT / "README.md").read_text()
    assert rt.START in readme and rt.END in readme, "README.md lost its results markers"
    shown = readme.split(rt.START, 1)[1].split(rt.END, 1)[0].lstrip("\n")
    assert shown == rt.table(), "README.md's results differ from `python benchmarks/results_table.py`: run it with " \
                                "--write README.md"


def test_every_cited_row_has_its_episodes():
    rt = _script()
    names = [f"{task}_pasta{suffix}" for task, _, _ in rt.TASKS for suffix in ("", "_learned")]
    names += [name for _, _, name, _, _ in rt.ABLATIONS]
    names += [name for name in rt.loop_names() if name not in names]
    cited = [name for name in names if (rt.RESULTS / f"{name}.json").exists()]  # the others read "not run"
    assert {f"{task}_pasta" for task, _, _ in rt.TASKS} <= set(cited), "every task has its heuristic row"
    for name in cited:
        summary = json.loads((rt.RESULTS / f"{name}.json").read_text())
        rows = [json.loads(line) for line in (rt.RESULTS / f"{name}.jsonl").read_text().splitlines() if line.strip()]
        assert summary["split"] == "test" and summary["episodes"] == 20 == len(rows), name
        assert sorted(r["seed"] for r in rows) == list(range(1000, 1020)), name
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


def test_no_episode_of_a_current_row_plans_a_skill_its_scene_leaves_out():
    """Every cited row run with the scene check (not marked †): no episode's plan uses a skill the scene leaves out."""
    from pasta.tasks import get_task
    from pasta.tasks.scene import floor_height, resolve_scene, scene_fit

    rt = _script()
    names = [f"{task}_pasta{suffix}" for task, _, _ in rt.TASKS for suffix in ("", "_learned")]
    names += [name for _, _, name, _, _ in rt.ABLATIONS] + rt.loop_names()
    checked = 0
    for name in dict.fromkeys(names):
        if not (rt.RESULTS / f"{name}.json").exists():
            continue
        summary = json.loads((rt.RESULTS / f"{name}.json").read_text())
        if rt.outside_scene(summary) or summary.get("method") == "flat":
            continue
        scene = resolve_scene(get_task(summary["task"]).scene(), floor_height(64))
        for line in (rt.RESULTS / f"{name}.jsonl").read_text().splitlines():
            row = json.loads(line) if line.strip() else None
            if row:
                assert not scene_fit(row["skeleton"], scene), (name, row["seed"], row["skeleton"])
                checked += 1
    assert checked >= 40  # at least the re-run crs and cut_rearrange rows
