"""How the learned cost rates a piece against itself moved along x, y and z: predicted / true Chamfer.

    .venv/bin/python benchmarks/cost_height.py [--models ROOT] [--tasks crs,lift_spread] [--seeds 1000-1019]

Held-out pieces: the goal entities of the tasks' test instances (seeds 1000-1019 by default, never in a training
set), decomposed and encoded as the planner sees them. Each latent is paired with itself with its centroid ``t``
moved by ``d`` along one axis (how the planner moves a sub-goal), and the cost model's prediction is compared with
the exact Chamfer of the cloud and its moved copy (``pasta.core.metrics.chamfer``, the cost's training label).
Prints, per axis and shift, the median and the 10th-90th percentiles of predicted / true and the share of pairs
within 20 %. A cost that is blind to height (all demonstration pieces rest on the floor) shows a y ratio far
below 1 (docs/planning.md, "Known model errors").
"""

from __future__ import annotations

import argparse
import sys

import numpy as np


def held_out_pieces(tasks: list[str], seeds: list[int], encoder, num_points: int = 1000):
    """``(latents (N, D), clouds (N, P, 3))`` of the goal entities of ``tasks`` x ``seeds``."""
    import torch

    from pasta.core.decompose import decompose
    from pasta.tasks import get_task

    latents, clouds = [], []
    for name in tasks:
        task = get_task(name)
        for seed in seeds:
            for piece in decompose(task.instance(seed).goal, min_points=50, num_points=num_points, seed=seed):
                clouds.append(piece)
    with torch.no_grad():
        for i in range(0, len(clouds), 64):
            latents.append(encoder.encode(torch.as_tensor(np.stack(clouds[i:i + 64]))))
    return torch.cat(latents), torch.as_tensor(np.stack(clouds))


def ratios(cost, latents, clouds, axis: int, shift: float, label_points: int = 400) -> np.ndarray:
    """Predicted / true Chamfer of every piece against itself moved by ``shift`` along ``axis`` (both signs)."""
    import torch

    from pasta.core.metrics import chamfer

    out = []
    for sign in (1.0, -1.0):
        offset = torch.zeros(3)
        offset[axis] = sign * shift
        moved = latents.clone()
        moved[:, -3:] += offset
        with torch.no_grad():
            predicted = torch.stack([cost.pairwise(a[None, None], b[None, None])[0, 0, 0] for a, b in zip(latents, moved)])
        part = clouds[:, :label_points]
        true = chamfer(part, part + offset)
        out.append((predicted / true).numpy())
    return np.concatenate(out)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--models", default="", help="models root (default: the shipped weights)")
    ap.add_argument("--tasks", default="", help="comma-separated tasks (default: every registered one but 'skill')")
    ap.add_argument("--seeds", default="1000-1019", help="instance seeds, A-B or a comma list (default: the test set)")
    ap.add_argument("--shifts", default="0.01,0.02,0.035,0.05", help="shifts in metres")
    args = ap.parse_args(argv)

    import torch

    from pasta.nn.config import PointVAEEncoderConfig, SetCostConfig
    from pasta.nn.cost import SetCostModel
    from pasta.nn.encoders import PointVAEEncoder
    from pasta.plugins import get_plugins
    from pasta.weights import models_root, module_dir

    torch.set_num_threads(1)
    tasks = [t for t in args.tasks.split(",") if t] or [t for t in get_plugins().tasks.names() if t != "skill"]
    low, _, high = args.seeds.partition("-")
    seeds = list(range(int(low), int(high) + 1)) if high else [int(s) for s in args.seeds.split(",")]
    root = models_root(args.models)
    encoder = PointVAEEncoder(PointVAEEncoderConfig(weights=str(module_dir(root, "vae"))))
    cost = SetCostModel(SetCostConfig(weights=str(module_dir(root, "cost"))))
    latents, clouds = held_out_pieces(tasks, seeds, encoder)
    print(f"{len(latents)} goal pieces of {', '.join(tasks)} (seeds {args.seeds}); cost {module_dir(root, 'cost')}")
    print("| axis | shift cm | median predicted / true | p10-p90 | within 20 % |")
    print("|---|---:|---:|---:|---:|")
    for axis, name in enumerate("xyz"):
        for shift in (float(s) for s in args.shifts.split(",")):
            r = ratios(cost, latents, clouds, axis, shift)
            print(f"| {name} | {100 * shift:.1f} | {np.median(r):.2f} | {np.percentile(r, 10):.2f}-{np.percentile(r, 90):.2f} "
                  f"| {100 * np.mean(np.abs(r - 1) <= 0.2):.0f} % |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
