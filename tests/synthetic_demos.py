"""Test data: synthetic demonstrations in the dataset format of :mod:`pasta.demos.data`, without the simulator.

Geometry follows the CRS generators of the paper's release (unit-cube workspace, y up, dough resting
at y = 0.0269), and each demonstration interpolates particle positions over ``steps`` steps:

- ``cut``: a box of length U(0.2, 0.35) is split at 0.10-0.12 from its left end; the left part slides
  0.1 to the left (two pieces appear once the gap exceeds DBSCAN's eps);
- ``push``: a piece of length U(0.1, 0.12) at x U(0.5, 0.65) is translated to x U(0.25, 0.3) and a new z;
- ``roll``: such a piece at x U(0.22, 0.32) is flattened in place to height U(0.016, 0.018), width 0.13,
  keeping its volume.

The tool is a small point template following a plausible path; actions are its velocity. This data is
for tests only (importable as ``synthetic_demos`` from any test: ``tests/`` is on the path through its
``conftest.py``). The three generators imitate the built-in skills' geometry and their names only label the dataset folders: this
module never consults the plugin registry (demonstrations of any registered skill come from
``pasta demos``, :mod:`pasta.demos`).
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from pasta.core.errors import InputError

BOTTOM = 0.0269
HEIGHT = 0.08
SKILLS = ("cut", "push", "roll")
TOOL_POINTS = 100
ACTION_DIM = 6


def _box_points(rng: np.random.Generator, n: int) -> np.ndarray:
    """``(n, 3)`` uniform coordinates in ``[0, 1]^3`` (positions inside a box, normalised)."""
    return rng.random((n, 3))


def _place(unit: np.ndarray, centre_x: float, centre_z: float, dims: np.ndarray) -> np.ndarray:
    """Map unit coordinates to a box of size ``dims (3,)`` resting on the floor at ``(centre_x, centre_z)``."""
    lo = np.array([centre_x - dims[0] / 2, BOTTOM, centre_z - dims[2] / 2])
    return lo + unit * dims


def _ease(s: np.ndarray) -> np.ndarray:
    return s * s * (3 - 2 * s)


def _tool(template: np.ndarray, positions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Tool points ``(T+1, Tp, 3)``, poses ``(T+1, 7)`` and actions ``(T, A)`` along ``positions (T+1, 3)``."""
    points = positions[:, None, :] + template[None]
    pose = np.concatenate([positions, np.tile([1.0, 0.0, 0.0, 0.0], (len(positions), 1))], 1)
    action = np.zeros((len(positions) - 1, ACTION_DIM))
    action[:, :3] = np.clip(np.diff(positions, axis=0) / 0.015, -1, 1)
    return points, pose, action


def _cut(rng: np.random.Generator, n: int, s: np.ndarray) -> tuple[np.ndarray, dict, np.ndarray]:
    length, depth = rng.uniform(0.2, 0.35), rng.uniform(0.06, 0.08)
    cx, cz = 0.9 - length / 2, 0.5 + rng.uniform(-0.2, 0.2)
    left_end = cx - length / 2
    cut_x = left_end + rng.uniform(0.1, 0.12)
    base = _place(_box_points(rng, n), cx, cz, np.array([length, HEIGHT, depth]))
    left = base[:, 0] < cut_x
    dough = np.repeat(base[None], len(s), 0)
    dough[:, left, 0] -= 0.1 * s[:, None]
    knife = np.stack([cut_x - 0.1 * s, BOTTOM + HEIGHT + 0.1 * (1 - np.minimum(2 * s, 1)), np.full_like(s, cz)], 1)
    params = {"length": length, "depth": depth, "cut_x": cut_x, "shift": -0.1, "centre_z": cz}
    return dough, params, knife


def _push(rng: np.random.Generator, n: int, s: np.ndarray) -> tuple[np.ndarray, dict, np.ndarray]:
    length, depth = rng.uniform(0.1, 0.12), rng.uniform(0.06, 0.08)
    x0, z0 = rng.uniform(0.5, 0.65), 0.5 + rng.uniform(-0.2, 0.2)
    x1, z1 = rng.uniform(0.25, 0.3), 0.5 + rng.uniform(-0.2, 0.2)
    base = _place(_box_points(rng, n), x0, z0, np.array([length, HEIGHT, depth]))
    offset = np.array([x1 - x0, 0.0, z1 - z0])
    dough = base[None] + s[:, None, None] * offset
    pusher = np.stack([x0 + length / 2 + 0.02 + s * offset[0], np.full_like(s, 0.05), z0 + s * offset[2]], 1)
    params = {"length": length, "depth": depth, "start": [x0, z0], "target": [x1, z1]}
    return dough, params, pusher


def _roll(rng: np.random.Generator, n: int, s: np.ndarray) -> tuple[np.ndarray, dict, np.ndarray]:
    length, depth = rng.uniform(0.1, 0.12), rng.uniform(0.06, 0.08)
    x0, z0 = rng.uniform(0.22, 0.32), 0.5 + rng.uniform(-0.2, 0.2)
    flat_h, flat_w = rng.uniform(0.016, 0.018), 0.13
    start = np.array([length, HEIGHT, depth])
    end = np.array([length * HEIGHT * depth / (flat_h * flat_w), flat_h, flat_w])
    unit = _box_points(rng, n)
    # Interpolating the box sides geometrically keeps the volume constant along the way.
    dims = np.exp(np.log(start)[None] + s[:, None] * (np.log(end) - np.log(start))[None])
    dough = np.stack([_place(unit, x0, z0, d) for d in dims])
    roller = np.stack([np.full_like(s, x0), BOTTOM + dims[:, 1] + 0.03, np.full_like(s, z0)], 1)
    params = {"length": length, "depth": depth, "centre": [x0, z0], "flat_height": flat_h, "flat_width": flat_w}
    return dough, params, roller


_MAKERS = {"cut": _cut, "push": _push, "roll": _roll}


def synthetic_demo(skill: str, *, seed: int, steps: int = 10, num_points: int = 1000, noise: float = 5e-4) -> dict:
    """One demonstration of ``skill`` as the dict of arrays stored in a ``demo_NNNNN.npz``."""
    if skill not in _MAKERS:
        raise InputError(f"synthetic demonstrations exist for {', '.join(SKILLS)}, not '{skill}'")
    if steps < 1 or num_points < 1:
        raise InputError(f"steps and num_points must be >= 1, got {steps} and {num_points}")
    rng = np.random.default_rng([seed, SKILLS.index(skill)])
    s = _ease(np.linspace(0.0, 1.0, steps + 1))
    dough, params, path = _MAKERS[skill](rng, num_points, s)
    dough = dough + rng.normal(0.0, noise, dough.shape)
    template = rng.uniform(-0.01, 0.01, (TOOL_POINTS, 3))
    tool_points, tool_pose, action = _tool(template, path)
    return {
        "dough": dough.astype(np.float32),
        "tool_points": tool_points.astype(np.float32),
        "tool_pose": tool_pose.astype(np.float32),
        "action": action.astype(np.float32),
        "skill": np.array(skill),
        "params": np.array(json.dumps({"generator": "synthetic", "seed": seed, **params})),
    }


def write_synthetic_dataset(
    out_dir: str | Path,
    *,
    per_skill: int = 20,
    skills: Sequence[str] = SKILLS,
    steps: int = 10,
    num_points: int = 1000,
    seed: int = 0,
) -> Path:
    """Write ``per_skill`` demonstrations of each skill and a manifest into ``out_dir``; return it."""
    root = Path(out_dir)
    for skill in skills:
        (root / skill).mkdir(parents=True, exist_ok=True)
        for i in range(per_skill):
            arrays = synthetic_demo(skill, seed=seed * 100_003 + i, steps=steps, num_points=num_points)
            np.savez_compressed(root / skill / f"demo_{i:05d}.npz", **arrays)
    manifest = {
        "format": "pasta-demos",
        "version": 1,
        "generator": "synthetic",
        "skills": {skill: per_skill for skill in skills},
        "steps": steps,
        "num_points": num_points,
        "seed": seed,
    }
    (root / "manifest.json").write_text(json.dumps(manifest, indent=2) + "\n")
    return root


def write_knife_dataset(out_dir: str | Path) -> Path:
    """3 synthetic cut demonstrations (4 steps, 400 points) whose actions have the knife's size (dx, dy), so a
    policy trained on them can drive the real cut skill."""
    root = write_synthetic_dataset(out_dir, per_skill=3, skills=("cut",), steps=4, num_points=400)
    for path in sorted((root / "cut").glob("demo_*.npz")):
        with np.load(path) as f:
            arrays = {k: f[k] for k in f.files}
        arrays["action"] = np.ascontiguousarray(arrays["action"][:, :2])
        np.savez_compressed(path, **arrays)
    return root
