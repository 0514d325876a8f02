"""Synthetic demonstrations in the fixed demo format (no simulator)."""

from __future__ import annotations

import json

import numpy as np
import pytest


def write_demo(path, *, steps=8, points=64, tool_points=20, seed=0, skill="push"):
    """A blob pushed by a paddle: ``action[t]`` (2,) moves the paddle and the blob by ``0.02 * action``."""
    rng = np.random.default_rng(seed)
    blob = (np.array([0.5, 0.05, 0.5]) + rng.normal(0, 0.02, (points, 3))).astype(np.float32)
    paddle = (np.array([0.56, 0.05, 0.5]) + rng.normal(0, 0.01, (tool_points, 3))).astype(np.float32)
    actions = np.stack([np.sin(np.arange(steps) * 0.9 + seed), np.cos(np.arange(steps) * 0.7)], 1).astype(np.float32) * 0.8
    dough, tool, pose = [blob], [paddle], [np.r_[paddle.mean(0), 1, 0, 0, 0]]
    for a in actions:
        d = np.array([a[0], 0.0, a[1]], np.float32) * 0.02
        dough.append(dough[-1] + d)
        tool.append(tool[-1] + d)
        pose.append(np.r_[tool[-1].mean(0), 1, 0, 0, 0])
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez(path, dough=np.stack(dough), tool_points=np.stack(tool), tool_pose=np.stack(pose).astype(np.float32),
             action=actions, skill=np.array(skill), params=np.array(json.dumps({"seed": seed})))
    return path


@pytest.fixture
def demo_dir(tmp_path):
    (tmp_path / "manifest.json").write_text(json.dumps({"skills": ["push"]}))
    for i in range(3):
        write_demo(tmp_path / "push" / f"demo_{i:05d}.npz", seed=i)
    return tmp_path


@pytest.fixture(autouse=True)
def one_torch_thread():
    """Tiny networks run fastest on one thread (and the CI machine is shared)."""
    import torch

    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)
