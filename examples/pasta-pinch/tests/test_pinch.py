"""pasta-pinch's own tests: pasta's reusable contract suites, nothing else needed (`pytest` in this folder
after `pip install -e .`)."""

from pasta.testing import PlannerContract, SkillContract


class TestPinch(SkillContract):
    skill_name = "pinch"


class TestBeam(PlannerContract):
    planner_name = "beam"
    planner_overrides = {"num_samples": 128}
