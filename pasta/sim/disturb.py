"""Disturbances: the world changing between two skill steps, as explicit state in, state out.

A robot cell meets these every day: a piece sticks to the tool and slides off target, a cut leaves two pieces
where one was planned, two pieces end up touching, someone drops a lump of dough beside a piece, the camera
is noisy and misses points. :func:`make_disturbance` builds one, seeded, from the simulator's state and the
pieces the last step produced; :meth:`Disturbance.apply` changes a :class:`~pasta.sim.SimState` and
:meth:`Disturbance.observe` the observations after it. A disturbance is plain arrays
(:meth:`Disturbance.to_npz`), so a logged run replays it exactly (``pasta replay --verify``).

Kinds (:data:`DISTURBANCES`):

- ``shift``: one produced piece slides 4-8 cm across the table, to a place at least ``GAP`` from every other
  piece and inside the workspace;
- ``split``: the largest produced piece is cut in two by a random vertical plane through its middle third; the
  halves move apart to a ``GAP`` gap (the perception's DBSCAN radius is 3 cm, so it sees two pieces);
- ``merge``: a produced piece is pushed along the line of centroids against its nearest other piece until
  they touch (closer than the particle spacing: one piece to the perception and to the simulator);
- ``lump``: a ball of 10-20 % of a produced piece's particles (same particle density) lands on the table
  ``GAP`` beside it; the observed subset grows at its own rate, so observed point counts stay masses;
- ``noise``: every later observation gets camera-like noise (a camera above the table: 3 mm along the
  vertical, 1.5 mm across; drawn anew at every env step) and loses a fixed 20 % of its points (an occluder:
  the same points for the rest of the episode, so a step can follow its piece by point identity).
"""

from __future__ import annotations

import io
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from pasta.core.errors import InputError

__all__ = ["DISTURBANCES", "GAP", "Disturbance", "NoisyView", "make_disturbance", "particle_labels"]

DISTURBANCES = ("shift", "split", "merge", "lump", "noise")
GAP = 0.04  # metres between a moved piece and the others: above the perception's DBSCAN radius (0.03)
SHIFT_RANGE = (0.04, 0.08)
LUMP_RANGE = (0.10, 0.20)
NOISE_SIGMA = (0.0015, 0.003, 0.0015)  # x, y (vertical: the camera's depth), z
DROPOUT = 0.2
WORKSPACE = (0.08, 0.92)  # x, z range a moved piece must stay inside (the tools' walls are at the cube's faces)


@dataclass
class Disturbance:
    """One disturbance as arrays (see the module docstring).

    Attributes:
        kind: one of :data:`DISTURBANCES`.
        step: the env step at which it happened.
        particles: ``(K,)`` indices of the particles it moved; ``offset``: ``(K, 3)`` their displacement.
        added: ``(A, 3)`` particles it added (``lump``), appended after the existing ones at rest (F = I).
        observed_added: ``(B,)`` indices into ``added`` that join the observed subset.
        dropped: ``(D,)`` positions in the observed subset that later observations lose (``noise``).
        seed: the seed of the observation noise (``noise``).
        description: one line for people: what changed, by how much.
    """

    kind: str
    step: int
    particles: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    offset: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), np.float32))
    added: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), np.float32))
    observed_added: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    dropped: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    seed: int = 0
    description: str = ""

    def apply(self, state: Any) -> Any:
        """The :class:`~pasta.sim.SimState` after the disturbance (a new one; ``state`` is not changed)."""
        st = state.copy()
        if len(self.particles):
            st.x[self.particles] += self.offset.astype(np.float32)
            st.v[self.particles] = 0.0
        if len(self.added):
            n, a = len(st.x), len(self.added)
            st.x = np.concatenate([st.x, self.added.astype(np.float32)])
            st.v = np.concatenate([st.v, np.zeros((a, 3), np.float32)])
            st.F = np.concatenate([st.F, np.tile(np.eye(3, dtype=np.float32), (a, 1, 1))])
            st.C = np.concatenate([st.C, np.zeros((a, 3, 3), np.float32)])
            st.obs_index = np.concatenate([st.obs_index, n + self.observed_added.astype(np.int64)])
        return st

    def apply_to(self, sim: Any) -> Any:
        """Disturb ``sim`` (a :class:`~pasta.sim.Simulator`) in place; returns what later steps observe through:
        ``sim`` itself, or a :class:`NoisyView` of it (``noise``)."""
        if self.kind == "noise":
            return NoisyView(sim, self)
        sim.set_state(self.apply(sim.get_state()))
        return sim

    def to_npz(self) -> bytes:
        buf = io.BytesIO()
        np.savez(buf, kind=np.array(self.kind), step=np.int64(self.step), particles=self.particles,
                 offset=self.offset, added=self.added, observed_added=self.observed_added, dropped=self.dropped,
                 seed=np.int64(self.seed), description=np.array(self.description))
        return buf.getvalue()

    @classmethod
    def from_npz(cls, data: bytes) -> Disturbance:
        with np.load(io.BytesIO(data), allow_pickle=False) as z:
            kind = str(z["kind"])
            if kind not in DISTURBANCES:
                raise InputError(f"a logged disturbance of unknown kind {kind!r}; kinds: {', '.join(DISTURBANCES)}")
            return cls(kind, int(z["step"]), z["particles"].astype(np.int64), z["offset"].astype(np.float32),
                       z["added"].astype(np.float32), z["observed_added"].astype(np.int64),
                       z["dropped"].astype(np.int64), int(z["seed"]), str(z["description"]))

    def summary(self) -> dict[str, Any]:
        """What changed, for the run log and the summary picture: kind, step, counts, mean displacement."""
        moved = float(np.linalg.norm(self.offset, axis=1).mean()) if len(self.offset) else 0.0
        return {"kind": self.kind, "applied": True, "step": int(self.step), "moved_particles": len(self.particles),
                "mean_displacement_m": round(moved, 4), "added_particles": len(self.added),
                "dropped_points": len(self.dropped), "description": self.description}


class NoisyView:
    """A simulator seen through a noisy camera: :meth:`observe` returns the dough without the disturbance's
    dropped points and with Gaussian noise drawn from (seed, env step); every other attribute is the
    simulator's. Scores are computed on the simulator itself, never on this view."""

    def __init__(self, sim: Any, disturbance: Disturbance) -> None:
        self.sim, self.disturbance = sim, disturbance

    def __getattr__(self, name: str) -> Any:
        return getattr(self.sim, name)

    def observe(self) -> Any:
        import dataclasses

        obs = self.sim.observe()
        keep = np.ones(len(obs.dough), bool)
        keep[self.disturbance.dropped[self.disturbance.dropped < len(keep)]] = False
        rng = np.random.default_rng([int(self.disturbance.seed), int(obs.step)])
        dough = obs.dough[keep] + rng.normal(0.0, NOISE_SIGMA, (int(keep.sum()), 3)).astype(np.float32)
        return dataclasses.replace(obs, dough=dough.astype(np.float32), dough_index=obs.dough_index[keep])


def particle_labels(x: np.ndarray, observed: np.ndarray, labels: np.ndarray) -> np.ndarray:
    """``(N,)`` the piece of every particle ``x (N, 3)``: the label of its nearest observed point."""
    from scipy.spatial import cKDTree

    _, nearest = cKDTree(np.asarray(observed, np.float64)).query(np.asarray(x, np.float64))
    return np.asarray(labels)[nearest]


def _clear(points: np.ndarray, others: np.ndarray, gap: float) -> bool:
    """``points`` lie inside the workspace and at least ``gap`` from ``others`` (x, z)."""
    lo, hi = WORKSPACE
    if points[:, [0, 2]].min() < lo or points[:, [0, 2]].max() > hi:
        return False
    if len(others) == 0:
        return True
    from scipy.spatial import cKDTree

    d, _ = cKDTree(others[:, [0, 2]]).query(points[:, [0, 2]])
    return bool(d.min() >= gap)


def _direction(rng: np.random.Generator) -> np.ndarray:
    a = rng.uniform(0.0, 2 * math.pi)
    return np.array([math.cos(a), 0.0, math.sin(a)])


def make_disturbance(kind: str, x: np.ndarray, pieces: np.ndarray, produced: list[int], *, step: int,
                     observed: int, seed: int) -> Disturbance:
    """A disturbance of ``kind`` for the scene ``x (N, 3)`` (every particle).

    Args:
        pieces: ``(N,)`` piece of every particle (:func:`particle_labels`).
        produced: the pieces the last step produced or acted on (the disturbed piece is drawn from them; the
            largest for ``split``).
        step: the env step now; ``observed``: the size of the observed subset (``noise`` drops 20 % of it).
        seed: the same seed and scene give the same disturbance.

    Raises:
        InputError: an unknown kind, no produced piece, or ``merge`` in a scene of one piece.
    """
    if kind not in DISTURBANCES:
        from pasta.core.errors import did_you_mean

        raise InputError(f"disturb={kind!r} is not a disturbance{did_you_mean(kind, DISTURBANCES)}; "
                         f"kinds: {', '.join(DISTURBANCES)}")
    rng = np.random.default_rng([int(seed), DISTURBANCES.index(kind), 4242])
    if kind == "noise":
        dropped = np.sort(rng.choice(observed, int(round(DROPOUT * observed)), replace=False)).astype(np.int64)
        return Disturbance(kind, step, dropped=dropped, seed=int(rng.integers(2**31)),
                           description=f"camera noise (sigma {1000 * NOISE_SIGMA[0]:.1f}/{1000 * NOISE_SIGMA[1]:.1f} mm "
                                       f"across/vertical) and {len(dropped)} of {observed} observed points lost")
    x = np.asarray(x, np.float64)
    produced = [int(p) for p in produced if np.any(pieces == p)]
    if not produced:
        raise InputError(f"disturb={kind}: the step produced no piece to disturb")
    sizes = {p: int(np.count_nonzero(pieces == p)) for p in produced}
    if kind == "split":
        target = max(produced, key=lambda p: (sizes[p], -p))
    else:
        target = produced[int(rng.integers(len(produced)))]
    members = np.flatnonzero(pieces == target)
    piece, others = x[members], x[pieces != target]
    centre = piece.mean(0)

    if kind == "shift":
        best = None
        for _ in range(64):
            move = _direction(rng) * rng.uniform(*SHIFT_RANGE)
            if _clear(piece + move, others, GAP):
                best = move
                break
        if best is None:
            raise InputError(f"disturb=shift: no place 4-8 cm away is free for piece {target} (64 tries)")
        return Disturbance(kind, step, members, np.tile(best, (len(members), 1)).astype(np.float32),
                           description=f"piece {target} ({len(members)} particles) slid "
                                       f"{100 * np.linalg.norm(best):.1f} cm across the table")
    if kind == "split":
        normal = _direction(rng)
        along = (piece - centre) @ normal
        cut = rng.uniform(-1.0, 1.0) * (along.max() - along.min()) / 6.0  # inside the middle third
        side = np.where(along > cut, 1.0, -1.0)
        if min(np.count_nonzero(side > 0), np.count_nonzero(side < 0)) < 10:
            raise InputError(f"disturb=split: piece {target} is too small to split")
        offset = side[:, None] * normal[None] * (GAP / 2)
        return Disturbance(kind, step, members, offset.astype(np.float32),
                           description=f"piece {target} ({len(members)} particles) split in two "
                                       f"({np.count_nonzero(side > 0)} / {np.count_nonzero(side < 0)}), "
                                       f"{100 * GAP:.0f} cm apart")
    if kind == "merge":
        if len(others) == 0:
            raise InputError("disturb=merge needs two pieces; the scene has one")
        from scipy.spatial import cKDTree

        other_ids = sorted(set(np.unique(pieces).tolist()) - {target})
        tree = cKDTree(piece)
        near = min(other_ids, key=lambda p: float(tree.query(x[pieces == p])[0].min()))
        partner = x[pieces == near]
        u = partner.mean(0) - centre
        u[1] = 0.0
        if np.linalg.norm(u) < 1e-6:
            raise InputError(f"disturb=merge: pieces {target} and {near} share a centre")
        u /= np.linalg.norm(u)
        spacing = float(np.median(tree.query(piece, k=2)[0][:, 1]))
        partner_tree = cKDTree(partner)
        lo, hi = 0.0, float(np.linalg.norm(partner.mean(0) - centre))  # at hi the centroids coincide: overlapping
        for _ in range(30):  # the shortest move that brings the two within one particle spacing
            mid = (lo + hi) / 2
            if float(partner_tree.query(piece + mid * u)[0].min()) > spacing:
                lo = mid
            else:
                hi = mid
        move = hi * u
        return Disturbance(kind, step, members, np.tile(move, (len(members), 1)).astype(np.float32),
                           description=f"piece {target} pushed {100 * hi:.1f} cm against piece {near}")
    # lump
    frac = rng.uniform(*LUMP_RANGE)
    count = max(10, int(round(frac * len(members))))
    from scipy.spatial import ConvexHull

    volume = float(ConvexHull(piece).volume) / len(members) * count
    radius = (3 * volume / (4 * math.pi)) ** (1 / 3)
    ball = rng.normal(size=(count, 3))
    ball *= (radius * rng.uniform(0, 1, count) ** (1 / 3) / np.linalg.norm(ball, axis=1))[:, None]
    floor = float(piece[:, 1].min())
    for _ in range(64):
        d = _direction(rng)
        reach = float(((piece - centre) @ d).max())
        at = centre + d * (reach + GAP + radius)
        at[1] = floor + radius
        if _clear(ball + at, x, GAP):
            break
    else:
        raise InputError(f"disturb=lump: no free place beside piece {target} (64 tries)")
    added = (ball + at).astype(np.float32)
    observed_added = np.flatnonzero(rng.uniform(size=count) < observed / len(x)).astype(np.int64)
    return Disturbance(kind, step, added=added, observed_added=observed_added,
                       description=f"a lump of {count} particles ({100 * count / len(members):.0f} % of piece "
                                   f"{target}) beside it")
