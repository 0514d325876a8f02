"""The results table names the paper's ablations and the raw method from what an eval summary recorded."""

from __future__ import annotations

import importlib.util
from pathlib import Path

_PATH = Path(__file__).resolve().parents[2] / "benchmarks" / "results_table.py"
_spec = importlib.util.spec_from_file_location("results_table", _PATH)
results_table = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(results_table)

SHIPPED = {"cut": {"hard_per_positive": 10, "shift_per_positive": 5}, "push": {"hard_per_positive": 10}}
CORRECTED = {"goal_mass": True, "goal_anchor": True}


def summary(**changes):
    base = {"method": "pasta", "feasibility_training": SHIPPED, "planner_settings": {"attention": "sample", "num_samples": 128},
            "execute_settings": CORRECTED}
    return {**base, **changes}


def test_a_default_run_has_no_label():
    assert results_table.ablation_labels(summary()) == ""
    assert results_table.ablation_labels({"method": "pasta"}) == ""  # runs before these were recorded


def test_each_ablation_is_named():
    label = results_table.ablation_labels
    none = {"cut": {"hard_per_positive": 0, "shift_per_positive": 0}, "push": {"hard_per_positive": 0}}
    assert label(summary(feasibility_training=none)) == ", no hard negatives"
    assert label(summary(feasibility_training={**none, "push": {"hard_per_positive": 10}})) == ""  # only some
    assert label(summary(planner_settings={"attention": "enumerate", "num_samples": 1})) == ", no sampling"
    assert label(summary(planner_settings={"attention": "enumerate", "num_samples": 4})) == ", 4 draws per attention structure"
    raw = {"goal_mass": False, "goal_anchor": False}
    assert label(summary(execute_settings=raw)) == ", raw: goal corrections off"
    assert label(summary(execute_settings={"goal_mass": False, "goal_anchor": True})) == ""
    assert label(summary(method="oracle", execute_settings=raw)) == ""


def test_planner_settings_other_than_the_planners_defaults_are_named():
    changes = results_table.planner_changes
    beam = {"name": "prefix_beam", "attention": "sample", "num_samples": 128, "final": 24, "max_horizon": 6, "width": 3}
    assert changes({"planner": "prefix_beam", "planner_settings": beam}) == "final=24, max_horizon=6"
    assert changes({"planner": "prefix_beam", "planner_settings": {**beam, "final": 6, "max_horizon": 0}}) == ""
    # the no-sampling ablation's own keys are its label, not repeated
    ablation = {"name": "exhaustive", "attention": "enumerate", "num_samples": 1, "refine_sequences": 0}
    assert changes({"planner": "exhaustive", "planner_settings": ablation}) == ""
    assert changes({"planner": "exhaustive"}) == ""  # runs that recorded no settings
    assert changes({"planner": "no_such_planner", "planner_settings": {"name": "no_such_planner", "x": 1}}) == ""


def test_execution_settings_other_than_the_defaults_are_named():
    changes = results_table.execute_changes
    assert changes(summary()) == ""  # the goal corrections have their own label
    assert changes({"execute_settings": {"controller": "learned", "skip_threshold": 0.001}}) == "skip_threshold=0.001"
    assert changes({"execute_settings": {"regress_stop": "off", "goal_mass": False}}) == ""  # labelled elsewhere
    assert changes({"method": "pasta"}) == ""  # runs that recorded no settings
