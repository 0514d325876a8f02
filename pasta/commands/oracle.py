"""``pasta oracle task=crs num=20``: run the ground-truth skill chains with the heuristic controllers."""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import asdict, dataclass

from pasta.core.errors import ConfigError

HELP = ("run a task's fixed test (or validation) set with the ground-truth skill chain and the heuristic "
        "point-cloud controllers; print normalised improvement and success rate (key=value: task, num, split, "
        "cache, json, task.<setting>)")


@dataclass
class OracleArgs:
    task: str = "crs"
    num: int = 20
    split: str = "test"  # "test": seeds 1000+; "val": the validation seeds 2000+ (choose settings there)
    cache: bool = True
    json: str = ""  # write per-episode results to this file


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("overrides", nargs="*", metavar="key=value", help="task=NAME num=20 split=test|val cache=true json=FILE task.<setting>=VALUE")


def run(args: argparse.Namespace) -> int:
    from pasta.config.overrides import build_many
    from pasta.config.validate import check_choice, check_output_file
    from pasta.tasks import fixed_test_seeds, fixed_val_seeds, get_task

    from pasta.tasks import split_task_settings

    task_settings, items = split_task_settings(list(args.overrides))
    opts = build_many(items, [OracleArgs], command="pasta oracle")[0]
    if opts.num <= 0:
        raise ConfigError(f"num must be >= 1, got {opts.num}")
    seeds = {"test": fixed_test_seeds, "val": fixed_val_seeds}[check_choice(opts.split, "split", ("test", "val"))]
    if opts.json:
        check_output_file(opts.json, "json")  # before any work
    task = get_task(opts.task, **task_settings)  # unknown task or setting -> error listing the known ones, before any work

    import numpy as np
    from rich.progress import Progress

    from pasta.tasks.oracle import run_oracle

    results = []
    sim = None
    with Progress(transient=True) as progress:
        bar = progress.add_task(f"oracle {task.name}", total=opts.num)
        for seed in seeds(opts.num):
            if sim is None:
                sim = task.make_sim()
            inst = task.instance(seed, sim=sim, cache=opts.cache)
            res = run_oracle(task, inst, sim)
            results.append(res)
            progress.console.print(
                f"seed {seed}: improvement {res.score.improvement:+.3f} emd {res.score.emd_initial:.4f} -> "
                f"{res.score.emd_final:.4f} {'success' if res.score.success else 'FAIL'} "
                f"steps {[r.steps for r in res.runs]} ({res.wall_s:.1f} s)"
            )
            progress.advance(bar)
    ni = np.array([r.score.improvement for r in results])
    ok = np.array([r.score.success for r in results])
    print(f"task {task.name}: {len(results)} episodes, threshold {task.threshold:.2f}")
    print(f"normalised improvement {ni.mean():.3f} +/- {ni.std():.3f}  success {ok.mean() * 100:.0f}% ({ok.sum()}/{len(ok)})")
    if opts.json:
        from pathlib import Path

        Path(opts.json).parent.mkdir(parents=True, exist_ok=True)
        with open(opts.json, "w") as fh:
            from pasta.io.provenance import provenance

            json.dump({"task": task.name, "split": opts.split, "threshold": task.threshold,
                       "provenance": provenance(sim_config=task.sim_config), "episodes": [
                {"seed": r.seed, **asdict(r.score), "steps": [x.steps for x in r.runs], "wall_s": r.wall_s} for r in results
            ]}, fh, indent=1)
    sys.stdout.flush()
    return 0
