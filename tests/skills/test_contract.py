"""The plugin contract suites for the built-in skills."""

from pasta.testing import SkillContract


class TestCut(SkillContract):
    skill_name = "cut"


class TestPush(SkillContract):
    skill_name = "push"


class TestRoll(SkillContract):
    skill_name = "roll"
