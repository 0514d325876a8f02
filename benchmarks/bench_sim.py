"""Simulator throughput on this machine. Prints a markdown table.

    .venv/bin/python benchmarks/bench_sim.py [--steps 20] [--particles 1000 3000 5000 10000]

Rows: a resting CRS dough box (every particle in the constitutive model, P2G, grid and G2P) with the
knife pressing into it, so tool contact is exercised. Last row: a 3-skill-like episode of 180 env
steps (60 cut, 60 push, 60 roll) at 5k particles. Timings are wall clock after a warm-up step
(kernels compiled or loaded from the offline cache); each row is the best of --repeat runs.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from pasta.sim import SimConfig, Simulator, crs_dough


def bench(sim: Simulator, n: int, steps: int, repeat: int) -> tuple[float, float]:
    """Best of ``repeat`` runs of ``steps`` env steps (the VM is shared: the minimum is the signal)."""
    best = float("inf")
    for _ in range(repeat):
        rng = np.random.default_rng(0)
        sim.reset(crs_dough(n, rng, floor_y=sim.floor_y, length=0.3, depth=0.07), seed=0)
        sim.set_tool_pose("knife", (0.72, sim.floor_y + 0.19, 0.5))
        sim.step({"knife": [0.0, -0.2]})  # warm-up
        t = time.perf_counter()
        for _ in range(steps):
            sim.step({"knife": [0.0, -0.2]})
        best = min(best, (time.perf_counter() - t) / steps)
    return best, best / sim.cfg.substeps


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
    ap.add_argument("--particles", type=int, nargs="+", default=[1000, 3000, 5000, 10000])
    ap.add_argument("--repeat", type=int, default=3, help="report the best of this many runs")
    ap.add_argument("--no-episode", action="store_true")
    args = ap.parse_args()
    cfg = SimConfig(max_particles=max(10000, max(args.particles)))
    t0 = time.perf_counter()
    sim = Simulator(cfg)
    sim.reset(crs_dough(1000, 0, floor_y=sim.floor_y), seed=0)
    sim.step()
    print(f"Taichi init + kernel compile/load + first step: {time.perf_counter() - t0:.1f} s")
    print()
    g = cfg.n_grid
    print(f"| particles | grid | substeps/s | particle-substeps/s | ms / env step ({cfg.substeps} substeps) |")
    print("|---:|---:|---:|---:|---:|")
    for n in args.particles:
        step_s, sub_s = bench(sim, n, args.steps, args.repeat)
        print(f"| {n} | {g}^3 | {1 / sub_s:,.0f} | {n / sub_s / 1e6:.2f} M | {step_s * 1e3:.1f} |")
    if not args.no_episode:
        el = episode(sim, 5000)
        print()
        print(f"3-skill-like episode, 180 env steps, 5000 particles: {el:.1f} s ({el / 180 * 1e3:.1f} ms / env step)")


if __name__ == "__main__":
    main()
