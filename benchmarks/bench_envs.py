"""Gymnasium environment throughput: env steps per second for 1, 2 and 4 environments. Prints a markdown table.

    .venv/bin/python benchmarks/bench_envs.py [--task push] [--envs 1 2 4] [--steps 60] [--repeat 2]

1 environment runs in this process (``gymnasium.make``); N > 1 in Gymnasium's ``AsyncVectorEnv`` (one spawned
process each); ``--backend ray``: every N in :class:`pasta.envs.RayVectorEnv` (one Ray actor each, a local Ray
instance). Random actions, the first test config (seed 1000). Each environment step is one simulator step
plus the EMD reward; each worker starts its own simulator (Taichi, from the offline cache), which is left out:
the clock runs over ``--steps`` vector steps after the reset and one warm-up step. The best of
``--repeat`` runs is the figure (the machine may be shared). The simulator uses ``sim.cpu_threads`` (2) threads
per environment, so on a 2-core machine more environments share the cores.
"""

from __future__ import annotations

import argparse
import os
import time


def _make(task: str):
    def make():
        import gymnasium

        import pasta.envs  # noqa: F401 - registers the ids in a spawned worker

        return gymnasium.make(f"pasta/{task}-v0", seeds=(1000,))

    return make


def steps_per_second(task: str, n: int, steps: int, backend: str = "async") -> float:
    import gymnasium

    if backend == "ray":
        from pasta.envs import RayVectorEnv

        env = RayVectorEnv(task, n, seeds=(1000,))
    else:
        env = _make(task)() if n == 1 else gymnasium.vector.AsyncVectorEnv([_make(task)] * n, context="spawn")
    try:
        env.reset(seed=0)
        env.step(env.action_space.sample())  # warm-up: kernels compiled or loaded
        t0 = time.perf_counter()
        for _ in range(steps):
            env.step(env.action_space.sample())
        return n * steps / (time.perf_counter() - t0)
    finally:
        env.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="push")
    parser.add_argument("--envs", type=int, nargs="+", default=[1, 2, 4])
    parser.add_argument("--steps", type=int, default=60)
    parser.add_argument("--repeat", type=int, default=2)
    parser.add_argument("--backend", choices=["async", "ray"], default="async",
                        help="async: Gymnasium's AsyncVectorEnv (1 env: in this process); ray: pasta.envs.RayVectorEnv")
    args = parser.parse_args()
    print(f"task {args.task}, {args.backend}, {args.steps} vector steps, best of {args.repeat}, {os.cpu_count()} CPUs\n")
    print("| environments | env steps / s | per environment |")
    print("|---:|---:|---:|")
    for n in args.envs:
        best = max(steps_per_second(args.task, n, args.steps, args.backend) for _ in range(args.repeat))
        print(f"| {n} | {best:.1f} | {best / n:.1f} |", flush=True)


if __name__ == "__main__":
    main()
