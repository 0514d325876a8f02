"""Entities of every demonstration step, with their latents: the input of feasibility and cost training.

:func:`encode_scenes` is the Flat 3D version: the whole scene as one entity.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from pasta.demos.data import Demo, demo_entities


@dataclass
class EncodedDemo:
    """One demonstration as entity sets.

    Attributes:
        demo: key (``"cut/00003"``); skill: its skill.
        latents: per step, ``(K_t, D)`` latents.
        clouds: per step, ``(K_t, P, 3)`` entity clouds (float32 tensors).
    """

    demo: str
    skill: str
    latents: list[torch.Tensor]
    clouds: list[torch.Tensor]


def encode_demos(demos: list[Demo], encoder: Any, *, num_points: int = 1000, stride: int = 1, seed: int = 0) -> list[EncodedDemo]:
    """Decompose every step of every demonstration and encode its entities with ``encoder``."""
    out = []
    for demo in demos:
        ents = demo_entities(demo, num_points=num_points, stride=stride, seed=seed)
        clouds = [torch.from_numpy(c) for c in ents.clouds]
        sizes = [len(c) for c in clouds]
        with torch.no_grad():
            latents = encoder.encode(torch.cat(clouds)).split(sizes)
        out.append(EncodedDemo(demo.key, demo.skill, list(latents), clouds))
    return out


def encode_scenes(demos: list[Demo], encoder: Any, *, num_points: int = 1000, stride: int | None = None,
                  seed: int = 0) -> list[EncodedDemo]:
    """The Flat 3D version of :func:`encode_demos`: every state is the whole dough as ONE entity.

    The states of a demonstration are its first step and the dough after the skill
    (:attr:`~pasta.demos.data.Demo.after`) with ``stride=None``; with ``stride`` every ``stride``-th
    step, then the dough after the skill. Each is resampled to ``num_points`` points (as
    :func:`pasta.execute.episode.perceive` does for a scene encoder) and encoded as ``(1, D)``.
    """
    from pasta.core.decompose import resample

    out = []
    for demo in demos:
        rng = np.random.default_rng([seed, demo.index])
        steps = [0] if stride is None else list(range(0, len(demo.dough), max(1, stride)))
        scenes = [demo.dough[t] for t in steps] + [demo.after]
        clouds = torch.from_numpy(np.stack([resample(s, num_points, rng) for s in scenes]))
        with torch.no_grad():
            latents = encoder.encode(clouds)
        out.append(EncodedDemo(demo.key, demo.skill, list(latents[:, None]), list(clouds[:, None])))
    return out


def changed_entities(a: torch.Tensor, b: torch.Tensor, *, threshold: float = 5e-4, points: int = 200) -> tuple[list[int], list[int]]:
    """Indices of the entities of ``a (Ka, P, 3)`` and ``b (Kb, P, 3)`` left after removing unchanged pairs.

    Pairs are removed greedily, closest first, while their Chamfer distance (on the first ``points``
    points of each cloud) is below ``threshold`` (:func:`pasta.core.matching.unchanged_pairs`, which the
    planning pipeline uses to keep such pieces out of the attention search).
    """
    from pasta.core.matching import unchanged_pairs

    pairs = unchanged_pairs(a, b, threshold=threshold, points=points)
    same_a, same_b = {i for i, _ in pairs}, {j for _, j in pairs}
    return [i for i in range(len(a)) if i not in same_a], [j for j in range(len(b)) if j not in same_b]
