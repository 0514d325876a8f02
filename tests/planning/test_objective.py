"""The log objective: the log of the unfloored plan score, with gradients where feasibility saturates."""

import torch

from pasta.core import Skill, SkillSpec
from pasta.planning.objective import log_objective, plan_score


class _LogitModel:
    """Feasibility ``sigmoid(w * sum(u_out))`` with a ``logits`` method, like SetFeasibility."""

    def __init__(self, w: float) -> None:
        self.w = w

    def logits(self, u_in: torch.Tensor, u_out: torch.Tensor) -> torch.Tensor:
        return self.w * u_out.sum((1, 2))

    def __call__(self, u_in: torch.Tensor, u_out: torch.Tensor) -> torch.Tensor:
        return torch.sigmoid(self.logits(u_in, u_out))


class _Push(Skill):
    spec = SkillSpec(name="push_t", n_in=1, n_out=1, tool="pusher")


def test_log_objective_is_log_of_unfloored_score():
    f = torch.tensor([[0.9, 0.5], [0.2, 0.99]])
    c = torch.tensor([0.001, 0.01])
    expected = plan_score(f, c, cost_weight=100.0, floor=0.0).log()
    assert torch.allclose(log_objective(f.log(), c, cost_weight=100.0), expected, atol=1e-6)


def test_log_feasibility_keeps_gradient_where_probability_saturates():
    skill = _Push()
    skill.attach_feasibility(_LogitModel(w=1.0))
    u_in = torch.zeros(1, 1, 4)
    u_out = torch.full((1, 1, 4), -50.0, requires_grad=True)  # logit -200: sigmoid underflows to 0
    assert float(skill.feasibility(u_in, u_out).detach()) == 0.0
    lf = skill.log_feasibility(u_in, u_out)
    assert torch.isfinite(lf).all() and float(lf.detach()) < -150
    (g,) = torch.autograd.grad(lf.sum(), u_out)
    assert torch.allclose(g, torch.ones_like(g), atol=1e-6)  # d log sigmoid(x) / dx = 1 - sigmoid(x) ~ 1


def test_log_feasibility_without_logits_falls_back_to_probability():
    skill = _Push()
    skill.attach_feasibility(lambda a, b: torch.full((a.shape[0],), 0.25))
    lf = skill.log_feasibility(torch.zeros(2, 1, 3), torch.zeros(2, 1, 3))
    assert torch.allclose(lf, torch.log(torch.tensor([0.25, 0.25])))
