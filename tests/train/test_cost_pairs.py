"""Cost-model training pairs: demonstration pairs, and translated copies with their exact Chamfer."""

from __future__ import annotations

import pytest
import torch

from pasta.core.errors import ConfigError
from pasta.core.metrics import chamfer
from pasta.train.cost import CostTrainConfig, entity_pairs
from pasta.train.feasibility import train_dict
from pasta.train.latents import EncodedDemo


def demos(n: int = 3, steps: int = 4, points: int = 60) -> list[EncodedDemo]:
    g = torch.Generator().manual_seed(0)
    out = []
    for k in range(n):
        clouds = [torch.rand(2, points, 3, generator=g) * 0.1 + 0.3 for _ in range(steps)]
        latents = [torch.cat([torch.rand(2, 2, generator=g), c.mean(1)], 1) for c in clouds]  # z (2), t = centroid
        out.append(EncodedDemo(f"cut/{k:05d}", "cut", latents, clouds))
    return out


def test_translated_pairs_keep_the_shape_move_the_centroid_and_carry_the_true_chamfer():
    cfg = CostTrainConfig(label_points=60, translated_fraction=0.5, translate_max=0.08)
    a, b, c = entity_pairs(demos(), cfg, seed=1)
    latents = torch.cat([u for d in demos() for u in d.latents])
    clouds = torch.cat([x for d in demos() for x in d.clouds])
    same_z = (a[:, :2] == b[:, :2]).all(1)
    moved = same_z & ((b[:, 2:] - a[:, 2:]).norm(dim=1) > 1e-7)
    assert 0.35 < float(moved.float().mean()) < 0.65
    offset = (b - a)[moved, 2:]
    assert float(offset.norm(dim=1).max()) <= 0.08 + 1e-6
    assert float(offset[:, 1].abs().max()) > 0.03  # heights move too, not only the table plane
    # the label of a moved pair is the Chamfer of the entity's cloud and that cloud moved by the offset
    index = [int((latents == row).all(1).nonzero()[0]) for row in a[moved]]
    want = chamfer(clouds[index], clouds[index] + offset[:, None, :])
    torch.testing.assert_close(c[moved], want, rtol=1e-4, atol=1e-7)


def test_without_translation_the_pairs_are_the_earlier_ones_and_the_config_is_unchanged():
    plain = entity_pairs(demos(), CostTrainConfig(label_points=60), seed=1)
    again = entity_pairs(demos(), CostTrainConfig(label_points=60, translated_fraction=0.0, translate_max=0.3), seed=1)
    for x, y in zip(plain, again):
        assert torch.equal(x, y)
    assert train_dict(CostTrainConfig(translated_fraction=0.25))["translated_fraction"] == 0.25
    with pytest.raises(ConfigError, match="translated_fraction"):
        CostTrainConfig(translated_fraction=1.5)
