"""What a gradient through the simulator costs: time and memory of pasta.sim.grad against the forward simulator.
Prints a markdown table.

    .venv/bin/python benchmarks/bench_grad.py [--particles 1000 5000] [--steps 10 100] [--repeat 2]

Scene: a CRS dough box with the knife cutting down through it for the first half of the steps and sliding
sideways for the rest (contact in every step), every other registered tool parked. Columns: the forward
simulator (``Simulator.step`` x steps), the differentiable rollout alone (no backward), and a full gradient
(rollout, a Chamfer loss to a shifted copy of the dough, backward to the actions and start poses); the
minimum over ``--repeat`` runs after a warm-up (kernels compiled or loaded from the offline cache). Memory:
the process's peak resident set after each size (it only grows; the gradient's own fields are allocated once
per process, the per-step checkpoints are 96 bytes a particle a step).
"""

from __future__ import annotations

import argparse
import resource
import time

import numpy as np
import torch

from pasta.plugins import get_plugins
from pasta.sim import SimConfig, Simulator, crs_dough
from pasta.sim.grad import chamfer, gradient, rollout


def _actions(steps: int) -> np.ndarray:
    a = np.zeros((steps, 2))
    a[: steps // 2, 1] = -0.4
    a[steps // 2:, 0] = 0.3
    return a


def _peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--particles", type=int, nargs="+", default=[1000, 5000])
    ap.add_argument("--steps", type=int, nargs="+", default=[10, 100])
    ap.add_argument("--repeat", type=int, default=2)
    args = ap.parse_args(argv)
    sim = Simulator(SimConfig(n_particles=max(args.particles)), tools=get_plugins().simulated_tools())
    print("| particles | env steps | forward sim (s) | differentiable rollout (s) | gradient (s) | gradient / forward "
          "| peak RSS (MB) |\n|---|---|---|---|---|---|---|")
    for n in args.particles:
        x = crs_dough(n, np.random.default_rng(0), floor_y=sim.floor_y, length=0.2, depth=0.06)
        target = torch.as_tensor(x + np.array([0.02, 0.0, 0.0], np.float32))
        for steps in args.steps:
            sim.reset(x, seed=0)
            sim.set_tool_pose("knife", (0.8, float(x[:, 1].max()) + 0.102, 0.5), 0.0)
            start = sim.get_state()
            acts = _actions(steps)
            times: dict[str, list[float]] = {"fwd": [], "roll": [], "grad": []}
            for rep in range(args.repeat + 1):
                t0 = time.perf_counter()
                for k in range(steps):
                    sim.step({"knife": acts[k]})
                t1 = time.perf_counter()
                sim.set_state(start)
                with torch.no_grad():
                    rollout(sim, {"knife": torch.as_tensor(acts)})
                t2 = time.perf_counter()
                gradient(sim, {"knife": acts}, lambda xs, t=target: chamfer(xs, t))
                t3 = time.perf_counter()
                if rep:  # the first round compiles or loads the kernels
                    times["fwd"].append(t1 - t0)
                    times["roll"].append(t2 - t1)
                    times["grad"].append(t3 - t2)
            fwd, roll, grad = (min(times[k]) for k in ("fwd", "roll", "grad"))
            print(f"| {n} | {steps} | {fwd:.2f} | {roll:.2f} | {grad:.2f} | {grad / fwd:.1f}x | {_peak_mb():.0f} |",
                  flush=True)


if __name__ == "__main__":
    main()
