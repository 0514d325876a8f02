"""``pasta run task=crs seed=S [method=pasta] [controller=...] [log=run.mcap] [summary=run.png]``: one task episode.

Perception (decompose + encode the observation and the goal) -> plan (the configured planner) ->
execution (learned policies or heuristic controllers) -> score (normalised EMD improvement). The
models are the shipped ones (:mod:`pasta.weights`) unless ``models=DIR`` names a ``pasta train`` root.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path
from typing import Any

from pasta.core.errors import ConfigError, did_you_mean

HELP = "plan and execute one task instance in the simulator and score it (task=crs seed=S [method=...] [controller=...])"

EPILOG = """examples:
  pasta run task=crs seed=1000                                # shipped weights, exhaustive planner, heuristic controllers
  pasta run task=crs seed=1000 log=runs/crs.mcap summary=runs/crs.png
  pasta run task=crs seed=1000 controller=learned models=models   # your own `pasta train` root
  pasta run task=crs seed=1000 method=flat                    # the Flat 3D baseline
  pasta run task=crs seed=3 planner=sampling execute.closed_loop=true
  pasta run task=crs seed=1000 skills=cut,push,roll             # plan with these skills only
  pasta run task=crs_distractors seed=1000 task.distractors=4  # a task setting: 4 pieces that must stay put
keys of this command: task method=pasta|sampling|flat|oracle models controller log summary horizon threads=1
skeleton=auto|true|false task.<setting> (a task config field, e.g. task.distractors=4 for crs_distractors)
execute.<field> (see docs/policies.md; the skeleton is given for crs_twice only,
as in the paper), skills=a,b,c (default: every registered skill with trained weights under the models
root; the others are left out with a warning; not used by method=oracle); every other key=value goes to
the run config (seed, planner, planner.*)."""

_OWN = ("task", "models", "controller", "log", "horizon", "skeleton", "method", "summary", "threads", "skills")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = EPILOG
    parser.add_argument("overrides", nargs="*", metavar="key=value", help="task=NAME is required")


def split_overrides(overrides: list[str]) -> tuple[dict[str, str], dict[str, Any], list[str]]:
    """``(own keys, execute.* fields as strings, the rest for the run config)``."""
    from pasta.execute import ExecuteConfig

    own: dict[str, str] = {}
    execute: dict[str, Any] = {}
    rest: list[str] = []
    fields = {f.name: f for f in dataclasses.fields(ExecuteConfig)}
    for item in overrides:
        key, eq, value = item.partition("=")
        key, value = key.strip(), value.strip()
        if not eq or not key:
            raise ConfigError(f"argument {item!r} must look like key=value")
        if key in _OWN:
            own[key] = value
        elif key.startswith("execute."):
            name = key[len("execute."):]
            if name not in fields:
                raise ConfigError(f"unknown key '{key}'{did_you_mean(name, fields)}; execute keys: {', '.join(fields)}")
            execute[name] = value
        else:
            rest.append(item)
    if "controller" in own:
        execute["controller"] = own.pop("controller")
    return own, execute, rest


def run(args: argparse.Namespace) -> int:
    from pasta.config import to_yaml
    from pasta.execute.session import build_session

    from pasta.tasks import split_task_settings

    task_settings, items = split_task_settings(list(args.overrides))
    own, execute_kw, rest = split_overrides(items)
    if not own.get("task"):
        raise ConfigError("`pasta run` needs task=NAME (e.g. task=crs)")
    threads, horizon = check_own(own)  # before anything is loaded or computed
    import torch

    if threads > 0:
        torch.set_num_threads(threads)  # see `pasta eval`: 1 is fastest on a shared CPU
    session = build_session(own["task"], method=own.get("method", "pasta"), models=own.get("models"),
                            config_overrides=rest, execute=execute_kw, horizon=horizon or None,
                            skeleton=own.get("skeleton", "auto"), skills=own.get("skills") or None,
                            task_settings=task_settings)
    print_skill_warning(session)
    seed = int(session.cfg.seed)
    sim = session.task.make_sim()  # starts Taichi, so the log records the runtime's real compile options
    logger = None
    if own.get("log"):
        from pasta.io import RunLogger
        from pasta.io.provenance import PROVENANCE_RECORD, provenance

        meta = {**{k: str(v) for k, v in session.describe().items()}, "seed": str(seed),
                "pasta": __import__("pasta").__version__}
        logger = RunLogger(own["log"], config_yaml=to_yaml(session.cfg) + "execute: "
                           + json.dumps(dataclasses.asdict(session.exe)) + "\n", metadata=meta)
    try:
        if logger is not None:  # versions, CPU and Taichi settings, so a run can be compared across machines
            logger.add_metadata(PROVENANCE_RECORD, provenance(sim_config=session.task.sim_config))
        out = session.episode(seed, logger=logger, sim=sim)
    except BaseException as exc:  # the log records why the run ended (status "failed"), then the error goes on
        if logger is not None:
            logger.close(error=exc)
        raise
    if logger is not None:
        logger.close()
    if out.plan is not None:
        print(out.plan.summary())
    if out.result is not None:
        for s in out.result.steps:
            moved = f" (plan step {s.plan_step + 1})" if s.plan_step not in (-1, s.step) else ""
            print(f"  executed {s.step + 1}. {s.skill:<6}{moved} on observed pieces {list(s.attended)}: {s.env_steps} steps"
                  f"{' (stopped: moving away from its goal)' if s.stopped else ' (done)' if s.done else ''}, "
                  f"improvement {s.normalized_improvement:.3f}")
        if out.result.diverged:
            print(f"simulation diverged: {out.result.diverged}", file=sys.stderr)
    verdict = "success" if out.success else "failure"
    print(f"task {session.task.name} seed {seed} ({session.method}): normalised improvement {out.improvement:.3f} "
          f"({verdict}, threshold {session.task.threshold})")
    if own.get("log"):
        print(f"run logged to {own['log']} (open in Foxglove, or `pasta replay {own['log']}`)")
    if own.get("summary"):
        path = write_summary(own["summary"], session, out)
        print(f"summary image: {path}")
    return 0


def check_own(own: dict[str, str]) -> tuple[int, int]:
    """Validate this command's own keys before any work: ``(threads, horizon)``; output paths
    (``log=``, ``summary=``) must be writable files, so a finished episode is never lost to a bad path."""
    from pasta.config.validate import check_int, check_output_file, check_threads

    threads = check_threads(own.get("threads", "1"), "threads")
    horizon = check_int(own.get("horizon") or 0, "horizon", low=0)
    for key in ("log", "summary"):
        if own.get(key):
            check_output_file(own[key], key)
    return threads, horizon


def print_skill_warning(session: Any) -> None:
    """The one line naming the skills left out for lack of weights (``pasta run`` and ``pasta eval``)."""
    line = session.skill_choice.warning() if session.skill_choice is not None else None
    if line:
        print(line, file=sys.stderr)


def write_summary(path: str | Path, session: Any, out: Any) -> Path:
    """The episode's PNG: initial, each step's decoded sub-goal pieces, final against goal."""
    from pasta.execute import decode_entities
    from pasta.execute.summary import save_summary

    inst = session.task.instance(out.seed)
    steps = []
    if out.plan is not None:
        for h, step in enumerate(out.plan.steps):
            steps.append((f"{h + 1}. {step.skill} (f={step.feasibility:.2f})",
                          decode_entities(session.encoder, step.subgoal, 400)))
    title = (f"{session.task.name} seed {out.seed}, {session.method}: normalised improvement {out.improvement:.3f} "
             f"({'success' if out.success else 'failure'})")
    return save_summary(path, initial=inst.init_points, goal=inst.goal, final=out.final_dough, subgoals=steps, title=title)
