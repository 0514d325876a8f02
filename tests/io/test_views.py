"""pasta.io.views: the view box fitted to the dough and tool outlines in a view."""

import math

import numpy as np
import pytest

from pasta.io import ToolPrimitive
from pasta.io.views import base_name, outline, view_box, within

TOP, SIDE = (0, 2), (0, 1)


def extent(poly):
    return poly.max(0) - poly.min(0)


def test_cube_outline_is_its_footprint_and_turns_with_yaw():
    cube = ToolPrimitive("pusher", "cube", (0.03, 0.1, 0.2), (0.5, 0.1, 0.4))
    poly = outline(cube, TOP)
    assert len(poly) == 4 and np.allclose(extent(poly), [0.03, 0.2]) and np.allclose(poly.mean(0), [0.5, 0.4])
    assert np.allclose(extent(outline(cube, SIDE)), [0.03, 0.1])
    turned = ToolPrimitive("pusher", "cube", (0.03, 0.1, 0.2), (0.5, 0.1, 0.4),
                           (math.cos(math.pi / 4), 0.0, math.sin(math.pi / 4), 0.0))  # 90 degrees about y
    assert np.allclose(extent(outline(turned, TOP)), [0.2, 0.03])


def test_cylinder_is_a_band_from_above_and_a_circle_from_the_side():
    roller = ToolPrimitive("roller", "cylinder", (0.06, 0.06, 0.15), (0.3, 0.05, 0.5))  # axis along z
    assert np.allclose(extent(outline(roller, TOP)), [0.06, 0.15])
    side = outline(roller, SIDE)
    assert len(side) >= 16 and np.allclose(np.linalg.norm(side - [0.3, 0.05], axis=1), 0.03)
    ball = ToolPrimitive("ball", "sphere", (0.1, 0.1, 0.1), (0.5, 0.5, 0.5))
    assert np.allclose(np.linalg.norm(outline(ball, TOP) - [0.5, 0.5], axis=1), 0.05, atol=1e-3)


def test_within_and_base_name():
    lo, hi = np.array([0.2, 0.0, 0.3]), np.array([0.8, 0.2, 0.7])
    assert within(ToolPrimitive("knife", "cube", (0.05, 0.2, 0.12), (0.5, 0.25, 0.5)), lo, hi)  # reaches down in
    assert not within(ToolPrimitive("knife", "cube", (0.05, 0.2, 0.12), (0.15, 0.8, 0.12)), lo, hi)  # parked
    assert base_name("gripper.1") == "gripper" and base_name("knife") == "knife" and base_name("a.b") == "a.b"


def test_view_box_fits_the_dough_and_bounds_the_panel_shapes():
    rng = np.random.default_rng(0)
    dough = rng.random((500, 3)) * [0.3, 0.02, 0.2] + [0.4, 0.02, 0.4]  # flat: 0.02 high
    lo, hi = view_box([dough])
    assert np.all(lo < dough.min(0)) and np.all(hi > dough.max(0))
    assert np.all((hi - lo)[[0, 2]] < 1.2 * np.array([0.3, 0.2]))  # a margin, not the workspace
    assert (hi - lo)[1] == pytest.approx(0.2 * (hi - lo)[0])  # the side view raised: room for a tool above
    strip = rng.random((500, 3)) * [0.6, 0.05, 0.02] + [0.2, 0.02, 0.5]  # long and thin: padded to 0.3
    lo, hi = view_box([strip])
    assert (hi - lo)[2] == pytest.approx(0.3 * (hi - lo)[0])
    assert np.all(lo < strip.min(0)) and np.all(hi > strip.max(0))
