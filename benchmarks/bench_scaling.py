"""Wall time of ``pasta demos`` and ``pasta eval`` under ``backend=local`` and ``backend=ray`` (docs/scaling.md).

Runs each configuration as its own ``pasta`` process (one at a time, fresh output folders, so nothing is
resumed), records ``uptime``'s 1-minute load before and after, checks that every backend wrote the same
demo files and the same eval rows (less timings and provenance), and prints a table.

    .venv/bin/python benchmarks/bench_scaling.py                          # demos push num=8, eval push num=4
    .venv/bin/python benchmarks/bench_scaling.py --demos 16 --episodes 8 --out /tmp/scaling

Ray's wall time includes starting a local Ray instance (no ``ray.address``) and its workers.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

PASTA = [sys.executable, "-m", "pasta"]
TIMING = {"wall_s", "plan_s", "execute_s", "provenance"}


def load() -> float:
    return os.getloadavg()[0]


def run(args: list[str]) -> tuple[float, float, float]:
    """(wall seconds, load before, load after) of ``pasta ARGS``; raises when it fails."""
    before = load()
    t0 = time.perf_counter()
    proc = subprocess.run(PASTA + args, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise SystemExit(f"pasta {' '.join(args)} failed ({proc.returncode}):\n{proc.stdout[-3000:]}")
    return wall, before, load()


def rows(path: Path) -> dict[int, dict]:
    out = {}
    for line in path.read_text().splitlines():
        row = {k: v for k, v in json.loads(line).items() if k not in TIMING}
        row["steps"] = [{k: v for k, v in s.items() if k != "wall_s"} for s in row.get("steps", [])]
        out[row["seed"]] = row
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--demos", type=int, default=8, help="push demos per configuration")
    ap.add_argument("--episodes", type=int, default=4, help="push eval episodes per configuration")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", default="runs/scaling")
    a = ap.parse_args()
    out = Path(a.out)
    shutil.rmtree(out, ignore_errors=True)
    w = a.workers
    table = []
    demo_cfgs = [("local", [f"workers={w}"]), ("ray", [f"workers={w}", "backend=ray", f"ray.num_cpus={w}"])]
    for name, extra in demo_cfgs:
        args = ["demos", "skill=push", f"num={a.demos}", f"out={out / 'demos' / name}", "seed=0"] + extra
        wall, l0, l1 = run(args)
        table.append((f"pasta {' '.join(a for a in args if not a.startswith('out='))}", wall, wall / a.demos, l0, l1))
    files = {name: {p.name: p.read_bytes() for p in sorted((out / "demos" / name / "push").glob("*.npz"))}
             for name, _ in demo_cfgs}
    same_demos = files["local"] == files["ray"] and len(files["local"]) == a.demos
    eval_cfgs = [("local0", []), ("local", [f"workers={w}"]),
                 ("ray", [f"workers={w}", "backend=ray", f"ray.num_cpus={w}"])]
    for name, extra in eval_cfgs:
        args = ["eval", "task=push", "method=pasta", f"num={a.episodes}", f"out={out / 'eval' / name}"] + extra
        wall, l0, l1 = run(args)
        table.append((f"pasta {' '.join(a for a in args if not a.startswith('out='))}", wall, wall / a.episodes, l0, l1))
    evals = {name: rows(out / "eval" / name / "push_pasta.jsonl") for name, _ in eval_cfgs}
    same_rows = evals["local0"] == evals["local"] == evals["ray"]
    print(f"| command | wall s | s per item | load before / after |\n|---|---|---|---|")
    for cmd, wall, per, l0, l1 in table:
        print(f"| `{cmd}` | {wall:.1f} | {per:.1f} | {l0:.1f} / {l1:.1f} |")
    print(f"\nsame demo files (bytes) local vs ray: {same_demos}; same eval rows (less timings) across the three: "
          f"{same_rows}; {os.cpu_count()} CPUs")


if __name__ == "__main__":
    main()
