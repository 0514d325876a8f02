"""Disturbances on a two-piece scene, without the simulator: each kind changes what it says, seeded."""

from __future__ import annotations

import numpy as np
import pytest

from pasta.core.decompose import decompose_labels
from pasta.core.errors import InputError
from pasta.sim.disturb import DISTURBANCES, GAP, Disturbance, NoisyView, make_disturbance, particle_labels
from pasta.sim.simulator import Observation, SimState


def _box(rng, centre, half, n):
    return (np.asarray(centre) + rng.uniform(-1, 1, (n, 3)) * np.asarray(half)).astype(np.float32)


@pytest.fixture
def scene():
    """Two slabs on the table 14 cm apart (x), 1200 and 800 particles; 400 observed."""
    rng = np.random.default_rng(0)
    x = np.concatenate([_box(rng, (0.35, 0.04, 0.5), (0.04, 0.02, 0.04), 1200),
                        _box(rng, (0.57, 0.04, 0.5), (0.03, 0.02, 0.03), 800)])
    n = len(x)
    obs = np.sort(rng.choice(n, 400, replace=False))
    state = SimState(x, np.zeros((n, 3), np.float32), np.tile(np.eye(3, dtype=np.float32), (n, 1, 1)),
                     np.zeros((n, 3, 3), np.float32), np.zeros((0, 6)), obs)
    pieces = particle_labels(x, x[obs], decompose_labels(x[obs]))
    return state, pieces


def _pieces(state):
    return int(decompose_labels(state.x[state.obs_index]).max()) + 1


def _disturb(kind, state, pieces, seed=3, produced=(0, 1)):
    return make_disturbance(kind, state.x, pieces, list(produced), step=7, observed=len(state.obs_index), seed=seed)


def test_the_scene_is_two_pieces(scene):
    state, pieces = scene
    assert _pieces(state) == 2
    assert sorted(np.bincount(pieces).tolist()) == [800, 1200]


def test_shift_slides_one_piece_4_to_8_cm_clear_of_the_other(scene):
    state, pieces = scene
    d = _disturb("shift", state, pieces)
    after = d.apply(state)
    moved = np.linalg.norm(after.x - state.x, axis=1)
    assert set(np.flatnonzero(moved > 0)) == set(d.particles.tolist())
    assert len(set(pieces[d.particles].tolist())) == 1  # one whole piece
    assert 0.04 <= moved.max() <= 0.08 and np.allclose(after.x[d.particles, 1], state.x[d.particles, 1])
    assert _pieces(after) == 2
    rest = np.setdiff1d(np.arange(len(state.x)), d.particles)
    gap = np.min(np.linalg.norm(after.x[d.particles][:, None, [0, 2]] - after.x[rest][None, :, [0, 2]], axis=-1))
    assert gap >= GAP - 1e-6
    assert "slid" in d.description and d.step == 7


def test_split_cuts_the_largest_piece_into_two_that_perception_sees(scene):
    state, pieces = scene
    d = _disturb("split", state, pieces)
    assert set(pieces[d.particles].tolist()) == {int(np.argmax(np.bincount(pieces)))}
    after = d.apply(state)
    assert _pieces(after) == 3
    assert np.allclose(np.linalg.norm(d.offset, axis=1), GAP / 2)


def test_merge_pushes_a_piece_against_its_neighbour_until_they_are_one(scene):
    state, pieces = scene
    d = _disturb("merge", state, pieces, produced=(1,))
    after = d.apply(state)
    assert _pieces(after) == 1
    moved = after.x[d.particles] - state.x[d.particles]
    assert moved[:, 0].max() < 0  # towards the other piece (it lies at smaller x)
    assert "pushed" in d.description


def test_merge_needs_two_pieces(scene):
    state, _ = scene
    with pytest.raises(InputError, match="two pieces"):
        make_disturbance("merge", state.x, np.zeros(len(state.x), np.int64), [0], step=0, observed=10, seed=0)


def test_lump_adds_10_to_20_percent_beside_a_piece_and_the_camera_sees_it(scene):
    state, pieces = scene
    d = _disturb("lump", state, pieces)
    after = d.apply(state)
    share = len(d.added) / np.bincount(pieces).astype(float)
    assert any(0.09 <= s <= 0.21 for s in share)
    assert len(after.x) == len(state.x) + len(d.added) and after.F.shape[0] == len(after.x)
    assert len(after.obs_index) > len(state.obs_index) and after.obs_index.max() < len(after.x)
    assert _pieces(after) == 3  # a separate lump
    assert np.all(after.x[len(state.x):, 1] >= state.x[:, 1].min() - 1e-6)  # on the table, not under it


def test_noise_drops_a_fixed_fifth_and_jitters_every_observation(scene):
    state, pieces = scene
    d = _disturb("noise", state, pieces)
    assert len(d.dropped) == 80 and d.apply(state).x.tolist() == state.x.tolist()

    class Sim:
        step = 5

        def observe(self):
            return Observation(state.x[state.obs_index], state.obs_index.copy(), {}, {}, step=self.step)

    sim = Sim()
    view = NoisyView(sim, d)
    a, b = view.observe(), view.observe()
    assert a.dough.shape == (320, 3) and np.array_equal(a.dough, b.dough)  # same env step, same picture
    assert not np.isin(a.dough_index, state.obs_index[d.dropped]).any()
    err = a.dough - state.x[a.dough_index]
    assert 0.001 < err[:, 0].std() < 0.002 and 0.002 < err[:, 1].std() < 0.004
    sim.step = 6
    assert not np.array_equal(view.observe().dough, a.dough)  # a new env step draws new noise
    assert view.step == 6  # everything else is the simulator's


@pytest.mark.parametrize("kind", DISTURBANCES)
def test_a_seed_gives_one_disturbance_and_it_survives_the_log(scene, kind):
    state, pieces = scene
    d = _disturb(kind, state, pieces, produced=(1,) if kind == "merge" else (0, 1))
    again = _disturb(kind, state, pieces, produced=(1,) if kind == "merge" else (0, 1))
    back = Disturbance.from_npz(d.to_npz())
    for field in ("particles", "offset", "added", "observed_added", "dropped"):
        assert np.array_equal(getattr(d, field), getattr(again, field))
        assert np.array_equal(getattr(d, field), getattr(back, field))
    assert (back.kind, back.step, back.seed, back.description) == (d.kind, d.step, d.seed, d.description)
    if kind != "noise":
        other = _disturb(kind, state, pieces, seed=4, produced=(1,) if kind == "merge" else (0, 1))
        assert not np.array_equal(other.apply(state).x, d.apply(state).x) or kind == "merge"


def test_an_unknown_kind_is_named_with_a_suggestion(scene):
    state, pieces = scene
    with pytest.raises(InputError, match="did you mean 'shift'"):
        make_disturbance("shfit", state.x, pieces, [0], step=0, observed=10, seed=0)
