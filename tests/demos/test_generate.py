"""Scene options of `pasta demos`: the wide push scene and its validation (no simulator)."""

import numpy as np
import pytest

from pasta.core.errors import ConfigError, InputError
from pasta.demos.generate import DemoConfig, demo_scene, validate


def test_wide_push_scene_covers_the_right_of_the_workspace():
    rng = np.random.default_rng(0)
    boxes = [demo_scene("push", rng, 0.0, "wide")[0] for _ in range(200)]
    xs = np.array([c[0] for c, _ in boxes])
    lengths = np.array([s[0] for _, s in boxes])
    assert xs.max() > 0.75 and lengths.max() > 0.2  # default push pieces start at x <= 0.7, length <= 0.12
    assert np.all(xs + lengths / 2 <= 0.93 + 1e-9)


def test_wide_scene_is_for_push_only(tmp_path):
    with pytest.raises(InputError, match="push"):
        demo_scene("cut", np.random.default_rng(0), 0.0, "wide")
    with pytest.raises(ConfigError, match="scene"):
        validate(DemoConfig(skill="cut", out=str(tmp_path), scene="wide"))
    with pytest.raises(ConfigError, match="scene"):
        validate(DemoConfig(skill="push", out=str(tmp_path), scene="wider"))
