"""Simulator throughput: the plugin-driven kernel next to the frozen pre-plugin kernel. Prints markdown tables.

    .venv/bin/python benchmarks/bench_sim.py [--steps 20] [--particles 1000 3000 5000] [--repeat 5]

Rows: a resting CRS dough box (every particle in the constitutive model, P2G, grid and G2P) with the
knife pressing into it, so tool contact is exercised, and the pusher and the roller parked (their
bounds are still tested at every touched grid node). The new kernel (tools as runtime field data,
``pasta/sim/engine.py``) and the legacy kernel (tools as compile-time constants,
``benchmarks/legacy_engine.py``) run the same scene and actions, interleaved repeat by repeat (the
2-core machine is shared: the minimum of each is the signal). Timings are wall clock after a warm-up
step. Last row: a 3-skill-like episode of 180 env steps (60 cut, 60 push, 60 roll) at 5k particles on
the new kernel.
"""

from __future__ import annotations

import argparse
import importlib.util
import time
from pathlib import Path

import numpy as np

from pasta.plugins import get_plugins
from pasta.sim import SimConfig, Simulator, crs_dough


def _legacy_module():
    path = Path(__file__).resolve().parent / "legacy_engine.py"
    spec = importlib.util.spec_from_file_location("pasta_legacy_engine", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _load(sim: Simulator, leg, n: int) -> None:
    sim.reset(crs_dough(n, np.random.default_rng(0), floor_y=sim.floor_y, length=0.3, depth=0.07), seed=0)
    st = sim.get_state()
    leg.set_state(st.x, st.v, st.F, st.C, st.tools)
    for target in (sim, leg):
        target.set_tool_pose("knife", (0.72, sim.floor_y + 0.19, 0.5))


def timed(target, steps: int) -> float:
    """Seconds per env step of ``steps`` knife-pressing steps after one warm-up step."""
    target.step({"knife": [0.0, -0.2]})
    t = time.perf_counter()
    for _ in range(steps):
        target.step({"knife": [0.0, -0.2]})
    return (time.perf_counter() - t) / steps


def episode(sim: Simulator, n: int) -> float:
    rng = np.random.default_rng(1)
    sim.reset(crs_dough(n, rng, floor_y=sim.floor_y, length=0.3, depth=0.07), seed=0)
    t = time.perf_counter()
    sim.set_tool_pose("knife", (0.72, sim.floor_y + 0.19, 0.5))
    for i in range(60):
        sim.step({"knife": [0.0, -1.0] if i < 12 else ([-0.3, 0.0] if i < 24 else [0.0, 1.0])})
    sim.park_tool("knife")
    left = sim.particles()[:, 0].min()
    sim.set_tool_pose("pusher", (left - 0.02, sim.floor_y + 0.052, 0.5))
    for i in range(60):
        sim.step({"pusher": [1.0 if i < 10 else 0.0, 0.0, 0.0, 0.0]})
    sim.park_tool("pusher")
    sim.set_tool_pose("roller", (0.65, sim.floor_y + 0.1, 0.5))
    for i in range(60):
        sim.step({"roller": [0.4 if (i // 15) % 2 == 0 else -0.4, 0.0, -0.3 if i < 20 else 0.0, 0.0]})
    sim.park_tool("roller")
    return time.perf_counter() - t


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--particles", type=int, nargs="+", default=[1000, 3000, 5000])
    ap.add_argument("--repeat", type=int, default=5, help="report the best of this many interleaved runs")
    ap.add_argument("--no-episode", action="store_true")
    args = ap.parse_args()
    cfg = SimConfig(max_particles=max(10000, max(args.particles)))
    t0 = time.perf_counter()
    sim = Simulator(cfg, tools=get_plugins().simulated_tools())
    sim.reset(crs_dough(1000, 0, floor_y=sim.floor_y), seed=0)
    sim.step()
    print(f"tools: {', '.join(sim.tool_names)}")
    print(f"Taichi init + kernel compile/load + first step (new kernel): {time.perf_counter() - t0:.1f} s")
    t0 = time.perf_counter()
    leg = _legacy_module().LegacySim(cfg)
    _load(sim, leg, 1000)
    leg.step()
    print(f"legacy kernel compile/load + first step: {time.perf_counter() - t0:.1f} s")
    print()
    best = {(n, k): float("inf") for n in args.particles for k in ("new", "legacy")}
    for r in range(args.repeat):
        for n in args.particles:
            order = (("new", sim), ("legacy", leg)) if r % 2 == 0 else (("legacy", leg), ("new", sim))
            for kind, target in order:
                _load(sim, leg, n)
                best[(n, kind)] = min(best[(n, kind)], timed(target, args.steps))
    g = cfg.n_grid
    print(f"best of {args.repeat} interleaved runs of {args.steps} env steps ({cfg.substeps} substeps each), grid {g}^3")
    print()
    print("| particles | new ms / env step | legacy ms / env step | slow-down | new particle-substeps/s |")
    print("|---:|---:|---:|---:|---:|")
    for n in args.particles:
        new, old = best[(n, "new")], best[(n, "legacy")]
        print(f"| {n} | {new * 1e3:.1f} | {old * 1e3:.1f} | {100 * (new / old - 1):+.1f} % | "
              f"{n * cfg.substeps / new / 1e6:.2f} M |")
    if not args.no_episode:
        el = episode(sim, 5000)
        print()
        print(f"3-skill-like episode, 180 env steps, 5000 particles (new kernel): {el:.1f} s ({el / 180 * 1e3:.1f} ms / env step)")


if __name__ == "__main__":
    main()
