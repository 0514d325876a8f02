"""``pasta run task=crs seed=S [log=run.mcap] [summary=run.png] [key=value ...]``: one task episode.

Perception (decompose + encode the observation and the goal) -> plan (the configured planner) -> check ->
execution (learned policies or heuristic controllers) -> score (normalised EMD improvement). Every setting
is a key of the run config (``pasta config task=crs`` prints them all); this command adds ``log=`` and
``summary=``.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pasta.commands._progress import planning_bar
from pasta.core.errors import ConfigError
from pasta.core.files import OutputLock

HELP = "plan and execute one task instance in the simulator and score it (task=crs seed=S [key=value ...])"

EPILOG = """examples:
  pasta run task=crs seed=1000                                # shipped weights, exhaustive planner, heuristic controllers
  pasta run task=crs seed=1000 log=runs/crs.mcap summary=runs/crs.png
  pasta run task=crs seed=1000 execute.controller=learned models=models   # your own `pasta train` root
  pasta run task=crs seed=1000 method=flat                    # the Flat 3D baseline
  pasta run task=crs seed=1000 method=trajopt                 # Traj-Opt: gradient descent through the simulator
  pasta run task=crs seed=3 planner=sampling
  pasta run task=crs seed=1000 skills=cut,push,roll           # plan with these skills only
  pasta run task=crs_distractors seed=1000 task.distractors=4 # a task setting
keys of this command: log=FILE.mcap summary=FILE.png log_time=sim|wall; every other key=value is a run-config key (`pasta config
task=crs` lists them: seed, method, models, horizon, skills, skeleton, planner, planner.*, perception.*,
check.*, execute.*, trajopt.*, sim.*, skill.<name>.*, task.*). controller=X is short for execute.controller=X."""


@dataclass
class RunArgs:
    """The keys of ``pasta run`` that are not run settings."""

    log: str = ""
    summary: str = ""
    #: the log's time axis: ``sim`` (simulation time, byte-reproducible) or ``wall`` (planning and slow steps
    #: take their real length on a viewer's timeline)
    log_time: str = "sim"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = EPILOG
    parser.add_argument("overrides", nargs="*", metavar="key=value", help="task=NAME is required")


def split_command_keys(items: list[str], cls: type) -> tuple[Any, list[str]]:
    """``(the command's own keys as a cls instance, the run-config items)``; ``controller=X`` is short for
    ``execute.controller=X``."""
    from dataclasses import fields

    from pasta.config import GROUPS
    from pasta.config.overrides import build
    from pasta.config.run import RunConfig
    from pasta.core.errors import did_you_mean

    mine = [f.name for f in fields(cls)]
    top = [f.name for f in fields(RunConfig)] + [g for g in GROUPS if g not in RunConfig.__dataclass_fields__]
    own: dict[str, str] = {}
    rest: list[str] = []
    for item in items:
        key, eq, value = item.partition("=")
        key, value = key.strip(), value.strip()
        if not eq or not key:
            raise ConfigError(f"argument {item!r} must look like key=value")
        if key in mine:
            own[key] = value
        elif key == "controller":
            rest.append(f"execute.controller={value}")
        elif key.split(".")[0] in top:
            rest.append(f"{key}={value}")
        else:
            raise ConfigError(f"unknown key '{key}'{did_you_mean(key, mine + top)}; keys of this command: "
                              f"{', '.join(mine)}; run-config keys: {', '.join(top)} (`pasta config` lists them all)")
    return build(cls, own), rest


def run(args: argparse.Namespace) -> int:
    from pasta.config.validate import check_output_file
    from pasta.execute.session import build_session

    opts, rest = split_command_keys(list(args.overrides), RunArgs)
    if not any(i.partition("=")[0] == "task" for i in rest):
        raise ConfigError("`pasta run` needs task=NAME (e.g. task=crs)")
    from pasta.config.validate import check_choice
    from pasta.io.run_log import CLOCKS

    check_choice(opts.log_time, "log_time", CLOCKS)
    for key in ("log", "summary"):  # before anything is computed: a finished episode is never lost to a bad path
        if getattr(opts, key):
            check_output_file(getattr(opts, key), key)
            OutputLock(getattr(opts, key), key).acquire()  # one writer per file: a second run stops here
    from pasta.config import load_config

    load_config(rest)  # every key and value is checked before a model is loaded or a simulator starts
    session = build_session(overrides=rest)
    apply_threads(session.cfg)
    print_skill_warning(session)
    seed = int(session.cfg.seed)
    sim = session.task.make_sim()  # starts Taichi, so the log records the runtime's real compile options
    logger = None
    if opts.log:
        from pasta.config import to_yaml
        from pasta.io import RunLogger
        from pasta.io.provenance import PROVENANCE_RECORD, provenance

        setup = session.describe()
        meta = {"task": session.task.name, "method": session.method, "seed": str(seed), "planner": str(setup["planner"]),
                "controller": setup["controller"], "skills": ",".join(setup["skills"]),
                "pasta": __import__("pasta").__version__, "log_time": opts.log_time}
        logger = RunLogger(opts.log, config_yaml=to_yaml(session.cfg), metadata=meta, clock=opts.log_time)
    try:
        if logger is not None:  # versions, CPU and Taichi settings, so a run can be compared across machines
            logger.add_metadata(PROVENANCE_RECORD, provenance(sim_config=session.task.sim_config))
        with planning_bar():  # on a terminal only
            out = session.episode(seed, logger=logger, sim=sim)
    except BaseException as exc:  # the log records why the run ended (status "failed"), then the error goes on
        if logger is not None:
            logger.close(error=exc)
        raise
    if logger is not None:
        logger.close()
    if out.plan is not None:
        print(out.plan.summary())
        for flag in out.plan.info.get("flags", []):
            print(f"warning: {flag['kind']}: {flag['message']}", file=sys.stderr)
    if out.result is not None:
        res = out.result
        for s in res.steps:
            print(f"  {s.describe()}")
            if s.step == 0 and res.disturbance:
                print(f"  disturbance ({res.disturbance['kind']}): {res.disturbance['description']}")
            for d in res.decisions:
                if d["after_step"] == s.step:
                    new = f": {' -> '.join(d['new'])}" if d["decision"] == "replanned" else ""
                    print(f"  closed loop: {d['decision']}{new} ({d['reason']}; {d['seconds']:.1f} s)")
        if out.result.diverged:
            print(f"simulation diverged: {out.result.diverged}", file=sys.stderr)
    opt = out.info.get("trajopt")
    if opt:
        best = opt["best_iteration"]
        print(f"  Traj-Opt ({' -> '.join(opt['skills'])}): {len(opt['losses'])} iterations in {out.plan_s:.0f} s, loss "
              f"{opt['losses'][0]:.4f} -> {opt['losses'][-1]:.4f}, executed the best (iteration {best}, loss "
              f"{opt['losses'][best]:.4f})")
    verdict = "success" if out.success else "failure"
    print(f"task {session.task.name} seed {seed} ({session.method}): normalised improvement {out.improvement:.3f} "
          f"({verdict}, threshold {session.task.threshold})")
    if opts.log:
        print(f"run logged to {opts.log} (open in Foxglove, or `pasta replay {opts.log}`)")
    if opts.summary:
        path = write_summary(opts.summary, session, out)
        print(f"summary image: {path}")
    return 0


def apply_threads(cfg: Any) -> None:
    """``threads=N`` (N > 0): torch's CPU threads for this process (1 is fastest on a shared CPU)."""
    if int(cfg.threads) > 0:
        import torch

        torch.set_num_threads(int(cfg.threads))


def print_skill_warning(session: Any) -> None:
    """The lines naming the skills left out: for the scene (the scene and why, on stdout) and for lack of
    weights (a warning on stderr); ``pasta run`` and ``pasta eval``."""
    choice = session.skill_choice
    if choice is None:
        return
    if choice.unmet:
        print(choice.scene_note())
    if choice.warning():
        print(choice.warning(), file=sys.stderr)


def write_summary(path: str | Path, session: Any, out: Any) -> Path:
    """The episode's PNG: initial, each plan step's decoded sub-goal under the dough observed after it ran (the
    improvement after it, the tool where it ended), final against goal."""
    from pasta.execute.summary import save_summary, summary_steps

    inst = session.task.instance(out.seed)
    steps, executed, start_tools, end_tools = summary_steps(out.plan, out.result, session.encoder)
    title = (f"{session.task.name} seed {out.seed}, {session.method}: normalised improvement {out.improvement:.3f} "
             f"({'success' if out.success else 'failure'})")
    return save_summary(path, initial=inst.init_points, goal=inst.goal, final=out.final_dough, subgoals=steps,
                        title=title, executed=executed, start_tools=start_tools, end_tools=end_tools)
