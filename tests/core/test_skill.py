import pytest
import torch

from pasta.core import InputError, MissingComponentError, PluginValidationError, Skill, SkillSpec


class Pinch(Skill):
    spec = SkillSpec("pinch", 2, 1, "gripper")


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"name": "Cut", "n_in": 1, "n_out": 2, "tool": "knife"}, "lower case"),
        ({"name": "cut", "n_in": 0, "n_out": 2, "tool": "knife"}, "n_in must be an integer >= 1"),
        ({"name": "cut", "n_in": 1, "n_out": 1.5, "tool": "knife"}, "n_out must be an integer >= 1"),
        ({"name": "cut", "n_in": 1, "n_out": 2, "tool": ""}, "tool must be a non-empty string"),
    ],
)
def test_skill_spec_rejects_bad_values(kwargs, message):
    with pytest.raises(PluginValidationError, match=message):
        SkillSpec(**kwargs)


def test_spec_delta_and_identity():
    skill = Pinch()
    assert (skill.name, skill.n_in, skill.n_out, skill.tool, skill.spec.delta) == ("pinch", 2, 1, "gripper", -1)


def test_missing_feasibility_names_skill_and_fix():
    with pytest.raises(MissingComponentError, match="skill 'pinch' has no feasibility predictor.*train feasibility skill=pinch"):
        Pinch().feasibility(torch.zeros(3, 2, 5), torch.zeros(3, 1, 5))


def test_missing_hooks_raise_clear_errors():
    skill = Pinch()
    for call in (skill.controller, skill.policy, skill.park_pose):
        with pytest.raises(MissingComponentError, match="pinch"):
            call()


def test_feasibility_shape_errors_name_cardinality():
    skill = Pinch()
    skill.attach_feasibility(lambda a, b: torch.ones(a.shape[0]))
    assert skill.feasibility(torch.zeros(4, 2, 5), torch.zeros(4, 1, 5)).shape == (4,)
    with pytest.raises(InputError, match="consumes 2 and produces 1"):
        skill.feasibility(torch.zeros(4, 1, 5), torch.zeros(4, 1, 5))
    with pytest.raises(InputError, match=r"U_in \(B, 2, D\)"):
        skill.feasibility(torch.zeros(4, 2), torch.zeros(4, 1, 5))


def test_skill_without_spec_is_rejected():
    class NoSpec(Skill):
        pass

    with pytest.raises(PluginValidationError, match="spec"):
        NoSpec()
