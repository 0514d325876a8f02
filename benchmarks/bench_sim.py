"""Simulator throughput: today's forward kernel next to the kernel of 2026-12-05 (frozen). Prints markdown tables.

    .venv/bin/python benchmarks/bench_sim.py [--steps 20] [--particles 1000 5000 20000] [--repeat 5]

Rows: a resting CRS dough box (every particle in the constitutive model, P2G, grid and G2P) with the
knife pressing into it, so tool contact is exercised, and the other tools parked (their bounds are still
tested at every touched grid node). Both kernels (``pasta/sim/engine.py`` and the frozen
``benchmarks/engine_v1.py``) run behind the same Simulator, at the same time step, substeps and particle
count, on the same scene and actions, interleaved repeat by repeat (the 2-core machine is shared: the
minimum of each is the signal), and end in the same state bit for bit (checked). Timings are wall clock after
a warm-up step. Last row: a 3-skill-like episode of 180 env steps (60 cut, 60 push, 60 roll) at 5k particles
on today's kernel.
"""

from __future__ import annotations

import argparse
import importlib.util
import time
from pathlib import Path

import numpy as np

from pasta.plugins import get_plugins
from pasta.sim import SimConfig, Simulator, crs_dough


def _v1_engine(cfg: SimConfig):
    """The frozen kernel of 2026-12-05 for this layout (benchmarks/engine_v1.py)."""
    path = Path(__file__).resolve().parent / "engine_v1.py"
    spec = importlib.util.spec_from_file_location("pasta_engine_v1", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.Engine(cfg.n_grid, cfg.max_particles)


def _load(sim: Simulator, n: int) -> None:
    sim.reset(crs_dough(n, np.random.default_rng(0), floor_y=sim.floor_y, length=0.3, depth=0.07), seed=0)
    sim.set_tool_pose("knife", (0.72, sim.floor_y + 0.19, 0.5))


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
    ap.add_argument("--particles", type=int, nargs="+", default=[1000, 5000, 20000])
    ap.add_argument("--repeat", type=int, default=5, help="report the best of this many interleaved runs")
    ap.add_argument("--no-episode", action="store_true")
    args = ap.parse_args()
    cfg = SimConfig(max_particles=max(10000, max(args.particles)))
    tools = get_plugins().simulated_tools()
    t0 = time.perf_counter()
    sim = Simulator(cfg, tools=tools)
    sim.reset(crs_dough(1000, 0, floor_y=sim.floor_y), seed=0)
    sim.step()
    print(f"tools: {', '.join(sim.tool_names)}")
    print(f"Taichi init + kernel compile/load + first step (today's kernel): {time.perf_counter() - t0:.1f} s")
    t0 = time.perf_counter()
    old = Simulator(cfg, tools=tools)
    old._eng = _v1_engine(cfg)  # the same Simulator code in front of the frozen kernel's fields and kernels
    _load(old, 1000)
    old.step()
    print(f"2026-12-05 kernel compile/load + first step: {time.perf_counter() - t0:.1f} s")
    print()
    kernels = {"new": sim, "v1": old}
    best = {(n, k): float("inf") for n in args.particles for k in kernels}
    same = {}
    for r in range(args.repeat):
        for n in args.particles:
            order = list(kernels.items()) if r % 2 == 0 else list(reversed(kernels.items()))
            for kind, target in order:
                _load(target, n)
                best[(n, kind)] = min(best[(n, kind)], timed(target, args.steps))
            same[n] = all(np.array_equal(getattr(sim.get_state(), f), getattr(old.get_state(), f))
                          for f in ("x", "v", "F", "C"))
    g = cfg.n_grid
    print(f"best of {args.repeat} interleaved runs of {args.steps} env steps ({cfg.substeps} substeps each, "
          f"dt {cfg.dt:g}), grid {g}^3")
    print()
    print("| particles | today ms / env step | 2026-12-05 ms / env step | speed-up | today particle-substeps/s "
          "| same final state |")
    print("|---:|---:|---:|---:|---:|---|")
    for n in args.particles:
        new, v1 = best[(n, "new")], best[(n, "v1")]
        print(f"| {n} | {new * 1e3:.1f} | {v1 * 1e3:.1f} | {v1 / new:.2f}x | {n * cfg.substeps / new / 1e6:.2f} M "
              f"| {'bitwise' if same[n] else 'no'} |")
    if not args.no_episode:
        el = episode(sim, 5000)
        print()
        print(f"3-skill-like episode, 180 env steps, 5000 particles (today's kernel): {el:.1f} s "
              f"({el / 180 * 1e3:.1f} ms / env step)")


if __name__ == "__main__":
    main()
