"""The four built-in planners honour the planner contract on the analytic problem (known optimum)."""

from __future__ import annotations

from pasta.testing import PlannerContract

FAST = {"iterations": 100}


class TestExhaustive(PlannerContract):  # every sample optimised to the end
    planner_name = "exhaustive"
    planner_overrides = {**FAST, "num_samples": 128, "halving_points": []}


class TestExhaustiveHalving(PlannerContract):  # the default: successive halving
    planner_name = "exhaustive"
    planner_overrides = {**FAST, "num_samples": 256}


class TestSampling(PlannerContract):
    planner_name = "sampling"
    planner_overrides = {**FAST, "num_samples": 512}


class TestRecedingHorizon(PlannerContract):
    planner_name = "receding_horizon"
    planner_overrides = {**FAST, "num_samples": 128, "window": 3}


class TestPrefixBeam(PlannerContract):
    planner_name = "prefix_beam"
    planner_overrides = {**FAST, "num_samples": 128}
