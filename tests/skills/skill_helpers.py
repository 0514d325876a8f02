"""Synthetic point clouds and a kinematic stand-in for the simulator (tools move, dough does not)."""

from __future__ import annotations

import numpy as np
from pasta.core import SkillObservation


def box(centre, size, n=600, seed=0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return (np.asarray(centre) + (rng.random((n, 3)) - 0.5) * np.asarray(size)).astype(np.float32)


def observation(piece, goal, pose, scene=None) -> SkillObservation:
    pose7 = np.zeros(7, np.float32)
    pose7[:3] = pose
    pose7[3] = 1.0
    return SkillObservation(piece=piece, goal=goal, tool_points=np.zeros((4, 3), np.float32), tool_pose=pose7, scene=scene)


def drive(controller, piece, goal, start, tool, max_steps=200):
    """Run ``controller`` with the tool moving kinematically (knife dx, dy; pusher dx, dz; roller roll, dy)."""
    pos = np.array(start, np.float64)
    from pasta.plugins import get_plugins

    scale = get_plugins().tools.info(tool).spec.action_scales
    obs = observation(piece, goal, pos)
    controller.reset(obs)
    actions = []
    for _ in range(max_steps):
        action, done = controller.act(obs)
        assert action.shape == ({"knife": 2, "pusher": 4, "roller": 4}[tool],)
        assert np.all(np.abs(action) <= 1.0 + 1e-6)
        if done:
            return actions, pos, True
        actions.append(action)
        if tool == "knife":
            pos[:2] += action * scale
        elif tool == "pusher":
            pos += np.array([action[0], action[1], action[2]]) * scale[0]
        else:
            pos[0] += action[0] * scale[0] * 0.03
            pos[1] += action[2] * scale[2]
        obs = observation(piece, goal, pos)
    return actions, pos, False
