"""pasta-press's own tests: pasta's reusable contract suite, and the skill's target (`pytest` in this folder
after `pip install -e .`)."""

import numpy as np

from pasta.testing import SkillContract
from pasta_press.skill import PressSkill, flattened


class TestPress(SkillContract):
    skill_name = "press"


def test_target_is_the_piece_flattened_at_the_same_volume():
    rng = np.random.default_rng(0)
    piece = rng.uniform([0.45, 0.0, 0.45], [0.51, 0.06, 0.51], (2000, 3)).astype(np.float32)
    out = flattened(piece, 0.5, 0.0)
    extent = lambda p: np.ptp(p, axis=0)  # noqa: E731
    np.testing.assert_allclose(extent(out), extent(piece) * [2 ** 0.5, 0.5, 2 ** 0.5], rtol=1e-5)
    np.testing.assert_allclose(out[:, [0, 2]].mean(0), piece[:, [0, 2]].mean(0), atol=1e-6)
    target = PressSkill().demo_target(piece, np.random.default_rng(1))
    keep = np.ptp(target[:, 1]) / np.ptp(piece[:, 1])
    assert 0.3 <= keep <= 0.42
