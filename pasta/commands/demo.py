"""``pasta demo``: the main job of ``make demo``.

For now it plans the analytic example problem (pasta.plugins.analytic) with the configured planner
and says so plainly; the simulator-backed CRS demo replaces it once the pipeline is trained.
"""

from __future__ import annotations

import argparse

from pasta.config import load_config, section
from pasta.plugins import get_plugins
from pasta.plugins.analytic import OPTIMAL_SKELETON, analytic_problem

HELP = "run the demo (currently: plan the analytic example problem with the configured planner)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("overrides", nargs="*", metavar="key=value", help="config overrides, e.g. planner=sampling")


def run(args: argparse.Namespace) -> int:
    cfg = load_config(args.overrides)
    planner = get_plugins().planners.create(cfg.planner.name, section(cfg, "planner"))
    print("pasta demo: ANALYTIC EXAMPLE (closed-form skills split/move/flatten, no simulator, no trained networks).")
    print(f"Planning with '{cfg.planner.name}': one piece -> goal of two pieces, horizon 3, seed {cfg.seed}.")
    plan = planner.plan(analytic_problem(seed=cfg.seed))
    print(plan.summary())
    found = plan.skills == OPTIMAL_SKELETON
    print(f"known optimum {' -> '.join(OPTIMAL_SKELETON)}: {'found' if found else 'NOT found'}")
    return 0 if found else 1
