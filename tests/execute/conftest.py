"""Test doubles for the executor: a box-decoding encoder and a pusher skill with a scripted controller."""

import numpy as np
import pytest
import torch

from pasta.core import Controller, Encoder, Skill, SkillSpec, ToolPose
from pasta.core.plan import Plan, PlanStep, as_latents


class BoxEncoder(Encoder):
    """Decodes u = [z0, z1, tx, ty, tz] to a fixed 0.1 x 0.06 x 0.06 box of points centred at t."""

    z_dim = 2

    def encode(self, points):
        return torch.cat([torch.zeros(len(points), 2), points.mean(1)], 1)

    def decode(self, latents, num_points):
        g = torch.Generator().manual_seed(0)
        box = (torch.rand(num_points, 3, generator=g) - 0.5) * torch.tensor([0.1, 0.06, 0.06])
        return latents[:, None, 2:5] + box

    def sample_prior(self, n, generator):
        return torch.rand(n, 5, generator=generator)


class PushLeft(Controller):
    """Pushes -x for ``n`` steps, then reports done."""

    def __init__(self, n):
        self.n, self.i = n, 0

    def act(self, obs):
        assert obs.piece.shape[1] == 3 and obs.goal.shape[1] == 3 and obs.tool_points.shape[1] == 3
        self.i += 1
        return np.array([-1.0, 0.0, 0.0, 0.0], np.float32), self.i >= self.n


class Nudge(Skill):
    spec = SkillSpec("nudge", 1, 1, "pusher", "test skill: push a piece a little towards -x")

    def approach_pose(self, piece, goal, scene=None):
        return ToolPose((float(piece[:, 0].max()) + 0.025, 0.06, float(piece[:, 2].mean())))

    def park_pose(self):
        return ToolPose((0.45, 0.8, 0.12))

    def controller(self):
        return PushLeft(4)


def make_plan(center, shift):
    u0 = [0.0, 0.0, *center]
    u1 = [0.0, 0.0, center[0] - shift, center[1], center[2]]
    step = PlanStep("nudge", (0,), as_latents([u1]), 1.0, as_latents([u1]))
    return Plan((step,), as_latents([u0]), as_latents([u1]), 0.0, 1.0, "hand", 0)



@pytest.fixture
def box_encoder():
    return BoxEncoder()


@pytest.fixture
def nudge():
    return Nudge()


@pytest.fixture
def one_step_plan():
    return make_plan
