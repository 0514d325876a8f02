"""Trainers and the pipeline never write through a link planted in ``out=`` (issue 41; tests/output_links.py)."""

from __future__ import annotations

from output_links import assert_regular, assert_untouched, plant_links, written_files
from pasta.cli import main

TINY_POLICY = {"epochs": "1", "steps_per_epoch": "2", "val_batches": "1", "batch_size": "4", "dough_points": "32",
               "tool_points": "8", "goal_points": "32"}


def _args(data, out, tiny):
    stage_args = [f"{stage}.{k}={v}" for stage, values in (*tiny.items(), ("policy", TINY_POLICY))
                  for k, v in values.items()]
    return ["pipeline", f"data={data}", f"out={out}", "stages=vae,feasibility,cost,policy", "skills=cut",
            "progress=false", *stage_args]


def test_pipeline_and_trainers_never_write_through_a_link(three_demos, tmp_path, tiny):
    first, out = tmp_path / "first", tmp_path / "out"
    assert main(_args(three_demos, first, tiny)) == 0
    names = written_files(first)
    for unit in ("vae", "feasibility/cut", "cost", "policy/cut"):
        assert f"{unit}/model.safetensors" in names and f"{unit}/model.json" in names, unit
    assert "pipeline.json" in names and "vae/metrics.json" in names
    planted = plant_links(out, names, tmp_path / "victims")
    assert main(_args(three_demos, out, tiny)) == 0
    assert_untouched(planted)
    assert_regular(out, names)
