"""Shared fixtures for the simulator tests: ONE Simulator per session (no recompiles per test)."""

from __future__ import annotations

import os

import numpy as np
import pytest

from pasta.plugins import get_plugins
from pasta.sim import SimConfig, Simulator, crs_dough, render_png


@pytest.fixture(scope="session")
def sim() -> Simulator:
    return Simulator(SimConfig(n_particles=3000, max_particles=10000), tools=get_plugins().simulated_tools())


@pytest.fixture
def fresh(sim):
    """The session simulator with default parameters restored; returns it."""
    cfg = SimConfig()
    sim.set_params(**{k: getattr(cfg, k) for k in sim.params},
                   **{f"{k}_friction": sim.tool_spec(k).friction for k in sim.tool_names})
    return sim


def dough(sim: Simulator, seed: int = 0, length: float = 0.3, depth: float = 0.07, shift_x: float = 0.0,
          n: int = 3000) -> np.ndarray:
    x = crs_dough(n, np.random.default_rng(seed), floor_y=sim.floor_y, length=length, depth=depth)
    return x + np.array([shift_x, 0.0, 0.0], dtype=np.float32)


def n_clusters(points: np.ndarray) -> int:
    from sklearn.cluster import DBSCAN

    labels = DBSCAN(eps=0.03, min_samples=6).fit_predict(points)
    return len(set(labels.tolist()) - {-1})


def snapshot(sim: Simulator, name: str, title: str = "") -> None:
    """Render a PNG when PASTA_SIM_PNG_DIR is set (for looking at the scenes)."""
    out = os.environ.get("PASTA_SIM_PNG_DIR")
    if out:
        o = sim.observe()
        render_png(os.path.join(out, f"{name}.png"), o.dough, o.tool_points, title=f"{name} {title}",
                   colors={t: sim.tool_spec(t).color for t in sim.tool_names})


@pytest.fixture(scope="session")
def helpers():
    """dough(sim, ...), n_clusters(points), snapshot(sim, name) as attributes."""
    from types import SimpleNamespace

    return SimpleNamespace(dough=dough, n_clusters=n_clusters, snapshot=snapshot)
