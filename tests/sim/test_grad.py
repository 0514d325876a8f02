"""Gradients through the simulator (pasta.sim.grad): the torch tool kinematics against Simulator.step, the
differentiable rollout against the forward simulator, analytic gradients against central finite differences,
reproducibility, the losses and bad input.

The finite-difference scene: a 1,000-particle dough, the knife 4 mm above it moving down and sideways for
three env steps (it cuts about 1.5 cm in), the pusher, 2 mm from the dough's end, pushing 4 mm into it in the
last step. The loss is a
fixed random linear function of the final particle positions, so every particle's motion counts.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch

from pasta.core.errors import InputError
from pasta.sim import crs_dough
from pasta.sim.grad import chamfer, gradient, rollout, sinkhorn, tool_rows

pytestmark = pytest.mark.sim

ACTIONS = {"knife": np.array([[0.1, -0.6], [0.05, -0.5], [-0.1, -0.4]]),
           "pusher": np.array([[0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0], [0.8, -0.2, 0.1, 0.2]])}


@pytest.fixture
def scene(fresh):
    """The session simulator holding the finite-difference scene; restores nothing (set_state callers do)."""
    x = crs_dough(1000, np.random.default_rng(3), floor_y=fresh.floor_y, length=0.2, depth=0.06)
    fresh.reset(x, seed=0)
    top = float(x[:, 1].max())
    lo = float(x[:, 0].min())
    fresh.set_tool_pose("knife", (0.8, top + 0.104, 0.5), 0.0)
    half = fresh.tool_spec("pusher").primitives[0].half
    fresh.set_tool_pose("pusher", (lo - 0.002 - half[0], fresh.floor_y + half[1] + 0.004, 0.5), 0.0)
    return fresh


def _loss(n: int):
    w = torch.as_tensor(np.random.default_rng(1).normal(size=(n, 3)), dtype=torch.float64)
    return lambda x: (x.double() * w).sum()


def test_tool_rows_are_the_simulators(scene):
    """The torch kinematics write the rows Simulator.step writes, for every movable tool, clipping included."""
    rng = np.random.default_rng(0)
    acts = {}
    for name in scene.tool_names:
        spec = scene.tool_spec(name)
        if spec.action_dim:
            acts[name] = rng.uniform(-1.3, 1.3, size=(3, spec.action_dim))  # beyond [-1, 1]: clipped
    start = scene.get_state()
    rows = tool_rows(scene, {k: torch.as_tensor(a) for k, a in acts.items()}).numpy().astype(np.float32)
    for k in range(3):
        scene.step({name: a[k] for name, a in acts.items()})
        np.testing.assert_allclose(scene._eng.tool.to_numpy(), rows[k], rtol=1e-6, atol=1e-6)
    scene.set_state(start)


def test_rollout_follows_the_forward_simulator_and_leaves_it_alone(scene):
    start = scene.get_state()
    x = rollout(scene, {k: torch.as_tensor(a) for k, a in ACTIONS.items()}, every_step=True).detach().numpy()
    np.testing.assert_array_equal(scene.get_state().x, start.x)  # the simulator did not move
    for k in range(3):
        scene.step({name: a[k] for name, a in ACTIONS.items()})
        # the same physics functions, SVD and summation order: the same floats (vector lengths whose gradient is
        # zero-safe differ below 1e-15, where nothing here lands)
        np.testing.assert_array_equal(x[k + 1], scene.get_state().x)
    assert np.abs(x[-1] - x[0]).max() > 2e-3  # the tools did move the dough
    scene.set_state(start)


def test_gradients_match_finite_differences(scene):
    """Every action entry that touches the dough and the knife's start position against central differences
    (measured: within 1-13 %; the forward model's contact band ends at 10 % influence, a jump that finite
    differences see and a gradient cannot). A wrong sign, a lost tool term or a lost step fails."""
    start = scene.get_state()
    loss = _loss(start.x.shape[0])
    value, g_act, g_pose = gradient(scene, ACTIONS, loss)

    def f(acts, poses=None):
        p = {k: torch.as_tensor(v) for k, v in (poses or {}).items()}
        return float(loss(rollout(scene, {k: torch.as_tensor(a) for k, a in acts.items()}, p)))

    assert value == pytest.approx(f(ACTIONS), rel=1e-6)
    checked = []
    for name, a in ACTIONS.items():
        for k in range(a.shape[0]):
            for c in range(a.shape[1]):
                if name == "pusher" and k < 2:
                    continue  # the pusher does not touch the dough before its step
                plus, minus = dict(ACTIONS), dict(ACTIONS)
                plus[name], minus[name] = a.copy(), a.copy()
                plus[name][k, c] += 1e-2  # 0.15 mm: smaller steps drown in the float32 rollout's rounding
                minus[name][k, c] -= 1e-2
                checked.append((f"{name}[{k},{c}]", g_act[name][k, c], (f(plus) - f(minus)) / 2e-2))
    for c in (0, 1):  # the knife's start position (the pusher's: the loss jumps where nodes cross its band edge)
        pose = scene.tool_state("knife")
        base = np.array([pose[k] for k in ("x", "y", "z", "yaw", "spin", "aperture")])
        plus, minus = base.copy(), base.copy()
        plus[c] += 1e-4
        minus[c] -= 1e-4
        checked.append((f"knife pose[{c}]", g_pose["knife"][c],
                        (f(ACTIONS, {"knife": plus}) - f(ACTIONS, {"knife": minus})) / 2e-4))
    for poses in (False, True):  # actions and poses differ 50x in size: each against its own largest entry
        rows = [r for r in checked if ("pose" in r[0]) == poses]
        scale = max(abs(fd) for _, _, fd in rows)
        for what, analytic, fd in rows:
            assert abs(analytic - fd) <= 0.2 * abs(fd) + 0.05 * scale, (what, analytic, fd)
    assert sum(abs(fd) > 1e-3 for _, _, fd in checked) >= 10  # the check is not of zeros
    scene.set_state(start)


def test_gradient_is_reproducible(scene):
    loss = _loss(scene.n_particles)
    _, g1, p1 = gradient(scene, ACTIONS, loss)
    _, g2, p2 = gradient(scene, ACTIONS, loss)
    for k in g1:
        np.testing.assert_array_equal(g1[k], g2[k])
    for k in p1:
        np.testing.assert_array_equal(p1[k], p2[k])


def test_every_step_loss_reaches_every_step(scene):
    """A loss on the middle state only: the last step's actions get no gradient, the first's do."""
    def loss(xs):
        return xs[2].sum() * 0 + (xs[2][:, 1]).sum()

    _, g, _ = gradient(scene, {"knife": ACTIONS["knife"]}, loss, every_step=True)
    assert np.all(g["knife"][2] == 0) and np.abs(g["knife"][:2]).max() > 0


def test_losses():
    rng = np.random.default_rng(0)
    a = torch.as_tensor(rng.uniform(size=(200, 3)), dtype=torch.float64)
    b = a + torch.tensor([0.05, 0.0, 0.0], dtype=torch.float64)
    assert float(chamfer(a, a)) < 1e-6 and float(chamfer(a, b)) > 0.04  # cdist rounds at 1e-8
    # a pure translation: the divergence is the squared shift, whatever the blur (the debiasing cancels it)
    for eps in (1e-3, 1e-4):
        assert float(sinkhorn(a, b, eps=eps, iters=300)) == pytest.approx(0.05**2, rel=0.02)
    # zero for equal clouds; a cloud shrunk toward the target's centre costs more than the target itself (plain
    # entropic OT at a large blur prefers the shrunk one, which an optimiser would find)
    shrunk = (a - a.mean(0)) * 0.5 + a.mean(0)
    assert abs(float(sinkhorn(a, a, eps=1e-2))) < 1e-12 and float(sinkhorn(shrunk, a, eps=1e-2)) > 1e-3
    moved = a.clone().requires_grad_(True)
    sinkhorn(moved, b, eps=1e-3).backward()
    assert float(moved.grad[:, 0].sum()) < 0  # moving the cloud towards +x lowers the cost
    # the gradient (envelope theorem, no unrolled iterations) against a central finite difference
    target = b + torch.as_tensor(rng.normal(scale=0.01, size=b.shape))
    moved = a.clone().requires_grad_(True)
    sinkhorn(moved, target, eps=1e-3).backward()
    step = torch.zeros_like(a)
    step[7, 0] = 1e-5
    fd = (float(sinkhorn(a + step, target, eps=1e-3)) - float(sinkhorn(a - step, target, eps=1e-3))) / 2e-5
    assert float(moved.grad[7, 0]) == pytest.approx(fd, rel=0.02)
    with pytest.raises(InputError, match="eps"):
        sinkhorn(a, b, eps=0.0)


def test_bad_input(scene):
    with pytest.raises(InputError, match="at least one tool"):
        rollout(scene, {})
    with pytest.raises(InputError, match=r"actions\['knife'\] must be a \(T, k\)"):
        rollout(scene, {"knife": torch.zeros(3)})
    with pytest.raises(InputError, match="NaN"):
        rollout(scene, {"knife": torch.full((2, 2), float("nan"))})
    with pytest.raises(InputError, match="same length"):
        rollout(scene, {"knife": torch.zeros(2, 2), "pusher": torch.zeros(3, 4)})
    with pytest.raises(InputError, match=r"poses\['knife'\]"):
        rollout(scene, {"knife": torch.zeros(2, 2)}, {"knife": torch.zeros(3)})
    with pytest.raises(Exception, match="spoon"):
        rollout(scene, {"spoon": torch.zeros(2, 2)})
    with pytest.raises(InputError, match="scalar"):
        gradient(scene, {"knife": np.zeros((1, 2))}, lambda x: x)
