"""Write dense obs/goal clouds for the `pasta plan` bounded-input measurement (docs/planning.md,
"Bounded inputs and checked results").

    .venv/bin/python benchmarks/dense_clouds.py OUT_DIR [--points 100000 1000000] [--task crs] [--seed 1000]
    /usr/bin/time -v .venv/bin/pasta plan obs=OUT_DIR/obs_1000000.npy goal=OUT_DIR/goal_1000000.npy out=OUT_DIR/plan

Each point of the task instance's observed (and goal) cloud is drawn with replacement and jittered by
Gaussian noise (sigma 0.004, clipped to the unit cube), so the dense cloud has the pieces of the original.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np


def dense(points: np.ndarray, n: int, rng: np.random.Generator, sigma: float = 0.004) -> np.ndarray:
    """``(n, 3)`` float32 points around ``points (P, 3)``."""
    picked = points[rng.integers(0, len(points), n)]
    return np.clip(picked + rng.normal(0.0, sigma, (n, 3)), 0.0, 1.0).astype(np.float32)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--points", type=int, nargs="+", default=[100_000, 1_000_000])
    parser.add_argument("--task", default="crs")
    parser.add_argument("--seed", type=int, default=1000)
    args = parser.parse_args()
    from pasta.tasks import get_task

    inst = get_task(args.task).instance(args.seed)
    args.out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(0)
    print(f"{'file':<24} {'points':>9}")
    for n in args.points:
        for name, cloud in (("obs", inst.init_points), ("goal", inst.goal)):
            path = args.out / f"{name}_{n}.npy"
            np.save(path, dense(np.asarray(cloud), n, rng))
            print(f"{path.name:<24} {n:>9}")


if __name__ == "__main__":
    main()
