"""``pasta demos skill=cut num=200 out=DIR [workers=2] [seed=0] [threads=0] [backend=local|ray] [deadline_s=0]``:
generate expert demonstrations."""

from __future__ import annotations

import argparse
import sys

HELP = ("generate demonstrations of a skill with its scripted expert on the scenes its plugin draws, or by "
        "trajectory optimisation toward the targets it draws "
        "(key=value: skill, num, out, workers, seed, settle_steps, idle_steps, n_particles, obs_points, scene, "
        "threads, expert=scripted|trajopt, trajopt_iterations, trajopt_steps, backend=local|ray, ray.address, "
        "ray.num_cpus, deadline_s); threads=N: the simulator's CPU threads "
        "in each worker (0, the default: the simulator's default, 2); any registered skill whose plugin defines "
        "demo_scene and an expert, or demo_scene and demo_target (expert=trajopt, its default then); resumable: existing demos are kept; backend=ray runs them as Ray tasks; a worker "
        "still on one demo after deadline_s seconds (0, the default: derived from the skill's max_steps and "
        "n_particles, about 11-13 min at the defaults) is given up and the demo retried (docs/scaling.md)")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("overrides", nargs="*", metavar="key=value", help="skill=cut num=200 out=DIR workers=2 seed=0 threads=0")


def run(args: argparse.Namespace) -> int:
    from pasta.demos.generate import DemoConfig, generate_demos, validate
    from pasta.demos.workers import DemoWorkerError
    from pasta.config.overrides import build_many
    from pasta.distributed import split_backend_args

    backend, rest = split_backend_args(args.overrides)
    backend.check()  # a missing Ray fails before anything is written
    cfg = build_many(rest, [DemoConfig], command="pasta demos")[0]
    validate(cfg)  # every bad argument fails here, before a simulator starts
    try:
        summary = generate_demos(cfg, backend=backend)
    except DemoWorkerError as exc:  # not a usage error (exit 2): the run itself could not finish
        print(f"pasta demos: error: {exc}", file=sys.stderr)
        return 1
    print(f"demos {cfg.skill}: {summary['generated']} generated, {summary['skipped']} already there, "
          f"{summary['wall_s']:.1f} s, {summary['mean_steps']:.1f} steps per demo on average -> {cfg.out}/{cfg.skill} "
          f"[{summary['backend']}]")
    return 0
