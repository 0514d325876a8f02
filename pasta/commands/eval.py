"""``pasta eval task=T method=M num=20``: a method's normalised improvement and success on a task's fixed test set.

Episodes run on the task's fixed test seeds (``pasta.tasks.fixed_test_seeds``: 1000, 1001, ...), or with
``split=val`` on its validation seeds (2000, 2001, ...: choose settings there, report the test seeds). Every
finished episode is appended to ``OUT/<task>_<method>[_<setting>...][_val].jsonl`` at once (:func:`result_path`),
so an interrupted evaluation resumes where it stopped (``resume=false`` starts over; a file of other settings
is never resumed); the summary (mean +/- std
of the normalised improvement, success rate, planning and execution seconds) is printed and written
next to it as ``.json``. Each episode's line (stderr) ends with an ETA: this run's mean episode time times
the episodes left, over the workers. With ``workers=N`` or ``backend=ray``, a worker still on one episode after
``deadline_s`` seconds (default :func:`episode_deadline`, from the task's horizon and step limits) is given
up and the episode retried once, then reported as failed.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pasta.core.errors import ConfigError
from pasta.core.files import OutputLock, append_text, refuse_link, write_json

HELP = "evaluate a method on a task's fixed test set (task=T [method=pasta|flat|oracle|trajopt] num=20 [key=value ...])"

EPILOG = """examples:
  pasta eval task=crs num=20
  pasta eval task=crs method=flat num=20
  pasta eval task=crs_twice num=20                       # receding horizon with the given skeleton, as in the paper
  pasta eval task=crs horizon=5 num=20                   # a longer planning horizon than the task needs
  pasta eval task=cut_rearrange method=oracle num=20     # the ground-truth chain with the heuristic controllers
  pasta eval task=crs method=trajopt num=5               # Traj-Opt: gradient descent on the chain's actions
  pasta eval task=crs skills=cut,push,roll               # plan with these skills only
  pasta eval task=crs_distractors num=10 task.distractors=4   # a task setting: its own instances and result file
  pasta eval task=crs workers=2                          # two episodes at a time, in local worker processes
  pasta eval task=crs backend=ray ray.address=auto       # episodes as Ray tasks on a cluster
  pasta eval task=crs workers=2 deadline_s=1800          # give up a worker still on one episode after 30 min
keys of this command: num split(test|val) out resume workers backend(local|ray) ray.address ray.num_cpus
deadline_s; every other key=value is a run-config key (`pasta config task=crs` lists them; controller=X is short
for execute.controller=X). The result file is OUT/<task>_<method>[_<setting>...][_val].jsonl, named by the
settings given; a file of other settings is never resumed.
deadline_s (workers or Ray only): seconds a worker may spend on one episode before it is killed (Ray: its task
cancelled) and the episode retried once, then reported as failed; 0 (the default) derives it from the task:
10 min of start-up and kernel compile, 200 s of planning per horizon step (none for method=oracle|trajopt) and 1 s per
simulator step (a Traj-Opt iteration counts 8 per env step of its chain) the episode may take at most (instance generation, then every step, 1 + execute.retries times, at
the longest max_steps of the skills planned with + execute.overrun + execute.idle_steps); crs: about 50 min."""


@dataclass
class EvalArgs:
    """The keys of ``pasta eval`` that are not run settings."""

    num: int = 20
    # "test": the fixed test seeds 1000, 1001, ... (report these); "val": 2000, 2001, ... (choose settings here)
    split: str = "test"
    out: str = "runs/eval"
    resume: bool = True
    # episodes at once: 0 runs them in this process; N in N local worker processes (backend=local) or at
    # most N Ray tasks in flight (backend=ray; 0: as many as the cluster has CPUs). docs/scaling.md
    workers: int = 0

    def __post_init__(self) -> None:
        from pasta.config.validate import check_choice, check_int
        from pasta.distributed import MAX_WORKERS
        from pasta.tasks.base import TEST_SEED_BASE, VAL_SEED_BASE

        # at most 1000 configs: the test seeds 1000, 1001, ... stop short of the validation seeds 2000, ...
        check_int(self.num, "num", low=1, high=VAL_SEED_BASE - TEST_SEED_BASE)
        check_choice(self.split, "split", ("test", "val"))
        check_int(self.workers, "workers", low=0, high=MAX_WORKERS)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = EPILOG
    parser.add_argument("overrides", nargs="*", metavar="key=value", help="task=NAME num=20 ...")


#: run-config keys that do not change an episode's result, left out of the result file's name
UNNAMED = ("task", "threads", "device")


def result_path(out: str | Path, cfg: Any, settings: list[str], split: str = "test") -> Path:
    """``OUT/<task>_<method>[_<setting>...][_val].jsonl``: one file per set of settings, the parts sorted.

    ``settings`` are the run-config items the user gave; each becomes a part of the name (``horizon=5`` ->
    ``_horizon5``, ``skills=cut,push`` -> ``_skills-cut-push``, ``task.distractors=4`` -> ``_distractors4``,
    ``execute.controller=learned`` -> ``_learned``, ``models=runs/ablation/nohn`` -> ``_models-nohn``: the
    weights root by its folder's name).
    """
    import re

    name = f"{cfg.task.name}_{cfg.method}"
    parts = []
    for item in settings:
        key, _, value = item.partition("=")
        key = key.strip()
        if key in UNNAMED or key == "method":
            continue
        if key == "execute.controller":
            parts.append(value.strip())
            continue
        leaf = key.split(".")[-1]
        if key == "models":
            value = Path(value.strip()).name
        value = re.sub(r"[^A-Za-z0-9.]+", "-", value.strip()).strip("-")
        parts.append(f"{leaf}{value}" if key.startswith("task.") or key == "horizon" else f"{leaf}-{value}")
    name += "".join(f"_{p}" for p in sorted(parts))
    name += "_val" if split == "val" else ""
    return Path(out) / f"{name}.jsonl"


def summarise(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Mean/std of the improvement, success rate and mean wall times of per-episode rows."""
    import numpy as np

    imp = np.array([r["improvement"] for r in rows], np.float64)
    return {"episodes": len(rows), "improvement_mean": float(imp.mean()) if len(rows) else float("nan"),
            "improvement_std": float(imp.std()) if len(rows) else float("nan"),
            "success_rate": float(np.mean([r["success"] for r in rows])) if rows else float("nan"),
            "plan_s_mean": float(np.mean([r.get("plan_s", 0.0) for r in rows])) if rows else 0.0,
            "execute_s_mean": float(np.mean([r.get("execute_s", 0.0) for r in rows])) if rows else 0.0}


@dataclass
class EvalState:
    """What a worker (or this process) reuses across episodes: the session, its simulator, the provenance."""

    session: Any
    sim: Any
    machine: dict[str, Any]


def eval_init(setup: dict[str, Any]) -> EvalState:
    """Build a worker's :class:`EvalState` from the evaluation's settings (:func:`pasta.distributed.map_jobs`)."""
    from pasta.commands.run import apply_threads
    from pasta.execute.session import build_session
    from pasta.io.provenance import provenance

    session = build_session(overrides=list(setup["overrides"]))
    apply_threads(session.cfg)
    sim = session.task.make_sim()  # it starts Taichi, whose settings the provenance records
    # versions, CPU, Taichi arch and compile options: results differ slightly between machines (docs/simulator.md)
    return EvalState(session, sim, provenance(sim_config=session.task.sim_config))


def eval_job(state: EvalState, seed: int, attempt: int) -> dict[str, Any]:
    """One episode's result row (the driver appends it to the result file), or ``{"seed", "refused",
    "exit_code"}`` when the episode was refused for a reason pasta names (a plan that fails its checks, a
    planner plugin that failed): nothing of it was executed."""
    from pasta.core.errors import PastaError

    t0 = time.perf_counter()
    try:
        out = state.session.episode(seed, sim=state.sim)
    except PastaError as exc:
        return {"seed": seed, "refused": f"{type(exc).__name__}: {exc}", "exit_code": int(getattr(exc, "exit_code", 2))}
    return {**out.to_dict(), "wall_s": round(time.perf_counter() - t0, 2), "setup": state.session.describe(),
            "provenance": state.machine}


#: the default deadline's planning allowance per horizon step (a crs plan takes 5-130 s on a 2-core machine)
PLAN_S = 200.0


def episode_deadline(session: Any) -> float:
    """The default ``deadline_s`` of ``pasta eval``: the most simulator steps an episode of ``session`` may
    take, sized by :func:`pasta.distributed.sized_deadline`, plus :data:`PLAN_S` per horizon step (none for
    the oracle and Traj-Opt, which do not plan; Traj-Opt's iterations count as :data:`pasta.sim.trajopt.GRADIENT_STEPS` steps per
    env step of its chain). The steps: generating the instance (the task's chain, on a cold task
    cache) and executing ``horizon`` steps, each up to ``1 + execute.retries`` times, every skill run at the
    longest step limit (``skill.<name>.max_steps``) of the skills planned with (the oracle: the task's
    chain) plus ``execute.overrun`` and ``execute.idle_steps``."""
    from pasta.config import section
    from pasta.distributed import STEP_PARTICLES, sized_deadline
    from pasta.execute.session import NO_PLANNER
    from pasta.sim.trajopt import GRADIENT_STEPS

    cfg, task = session.cfg, session.task
    exe = section(cfg, "execute")
    horizon = int(cfg.horizon or task.horizon)
    names = {getattr(sk, "name", "") for sk in getattr(session, "skills", None) or ()} | set(task.skeleton)
    limits = cfg.get("skill") or {}
    longest = max((int(limits[n].get("max_steps", 50)) for n in names if n in limits), default=50)
    tcfg = getattr(task, "config", None)
    idle, settle = int(getattr(tcfg, "idle_steps", 10)), int(getattr(tcfg, "settle_steps", 10))
    generate = settle + len(task.skeleton) * (longest + idle)
    execute = horizon * (1 + int(exe.retries)) * (longest + int(exe.overrun) + int(exe.idle_steps))
    plan = 0.0 if str(cfg.method) in NO_PLANNER else PLAN_S * horizon
    if str(cfg.method) == "trajopt":  # each iteration a rollout and its backward
        chain = len(task.skeleton) * int(cfg.trajopt.steps)
        execute = chain + idle + GRADIENT_STEPS * int(cfg.trajopt.iterations) * chain
    return sized_deadline(generate + execute, int(getattr(tcfg, "n_particles", STEP_PARTICLES)), plan)


def run(args: argparse.Namespace) -> int:
    from pasta.commands._progress import eta
    from pasta.commands.run import print_skill_warning, split_command_keys
    from pasta.config.validate import check_output_dir, check_output_file
    from pasta.distributed import BackendError, map_jobs, split_backend_args
    from pasta.tasks import fixed_test_seeds, fixed_val_seeds

    backend, items = split_backend_args(list(args.overrides))
    backend.check()  # a missing Ray fails before any model is loaded
    opts, rest = split_command_keys(items, EvalArgs)
    if not any(i.partition("=")[0] == "task" for i in rest):
        raise ConfigError("`pasta eval` needs task=NAME (e.g. task=crs)")
    if any(i.partition("=")[0] == "seed" for i in rest):
        raise ConfigError("pasta eval runs the fixed test seeds (1000, 1001, ...); use num=N, not seed=")
    check_output_dir(opts.out, "out")  # before any model is loaded: a bad out= must not cost an evaluation
    from pasta.config import load_config

    cfg = load_config(rest)  # every key and value is checked before a model is loaded or a simulator starts
    path = result_path(opts.out, cfg, rest, opts.split)
    check_output_file(path, "out")  # e.g. a directory of the result file's name in out=
    refuse_link(path, "out")  # the result file is appended to: a link there would be followed
    OutputLock(path, "out").acquire()  # one writer per result file (released when the command ends)
    setup = {"overrides": list(rest)}
    state = eval_init(setup)  # this process's session: the summary, the episodes with workers=0
    session, machine = state.session, state.machine
    print_skill_warning(session)
    path.parent.mkdir(parents=True, exist_ok=True)
    done: dict[int, dict[str, Any]] = {}
    if opts.resume and path.exists():
        for number, line in enumerate(path.read_text().splitlines(), 1):
            if line.strip():
                try:
                    row = json.loads(line)
                    done[int(row["seed"])] = row
                except (ValueError, KeyError, TypeError) as exc:
                    raise ConfigError(f"out={opts.out}: line {number} of {path} is not a result row ({exc}); "
                                      "fix or delete it, or pass resume=false to start over") from None
                if _settings(row.get("setup")) != _settings(session.describe()):
                    raise ConfigError(f"out={opts.out}: {path} holds episodes of other settings (line {number}, "
                                      f"seed {row['seed']}); pass resume=false to start over, or another out=")
    elif path.exists():
        path.unlink()
    seeds = fixed_test_seeds(opts.num) if opts.split == "test" else fixed_val_seeds(opts.num)
    todo = [s for s in seeds if s not in done]
    print(f"eval {session.task.name} / {session.method}: {len(seeds)} {opts.split} configs, {len(seeds) - len(todo)} already in {path}",
          file=sys.stderr)
    where = "" if backend.name == "local" and not opts.workers else f" on {backend.describe()}" + (
        f" with {opts.workers} workers" if opts.workers else "")
    deadline = backend.deadline_s or episode_deadline(session)  # not used by episodes run in this process
    failed: dict[int, str] = {}
    refused: dict[int, int] = {}  # seed -> exit code of an episode refused for a named reason
    walls: list[float] = []  # wall seconds of the episodes finished in this run (not the resumed ones: another machine)

    def left() -> str:
        """``, ETA 3m20s`` after an episode's line: this run's mean episode time x the episodes left / the workers."""
        # workers=0 counts as one at a time: with backend=ray it runs as many as the cluster has CPUs, and the
        # ETA is then an upper bound
        text = eta(walls, len(seeds) - len(done) - len(failed), opts.workers or 1)
        return f", {text}" if text else ""

    try:
        for outcome in map_jobs(eval_init, eval_job, setup, todo, backend=backend, workers=opts.workers,
                                deadline_s=deadline, label="episode", prog="pasta eval", state=state):
            seed = int(outcome.item)
            if not outcome.ok:
                failed[seed] = outcome.error or ""
                print(f"[{len(done) + len(failed)}/{len(seeds)}] seed {seed}: failed, {failed[seed].splitlines()[0]}"
                      f"{left()}", file=sys.stderr, flush=True)
                continue
            row = outcome.value
            if "refused" in row:  # nothing of this episode ran: reported, not written
                failed[seed] = row["refused"]
                refused[seed] = int(row["exit_code"])
                print(f"[{len(done) + len(failed)}/{len(seeds)}] seed {seed}: refused, {row['refused']}{left()}",
                      file=sys.stderr, flush=True)
                continue
            append_text(path, json.dumps(row) + "\n")  # one line per finished episode: nothing is lost on interruption
            done[seed] = row
            walls.append(float(row.get("wall_s", 0.0)))
            skel = "-".join(row.get("skeleton", [])) or "ground truth"
            print(f"[{len(done) + len(failed)}/{len(seeds)}] seed {seed}: {skel:<24} improvement {row['improvement']:+.3f} "
                  f"{'success' if row['success'] else 'failure'}  (plan {row['plan_s']:.1f} s, execute {row['execute_s']:.1f} s)"
                  f"{where}{left()}", file=sys.stderr, flush=True)
    except BackendError as exc:  # workers could not start, or the cluster is unreachable: not a usage error
        print(f"pasta eval: error: {exc} ({len(done)} of {len(seeds)} episodes are in {path}; "
              "run the same command again to continue)", file=sys.stderr)
        return 1
    if failed:
        first = min(failed)
        lines = [f"pasta eval: error: {len(failed)} of {len(seeds)} episodes of {session.task.name} / {session.method} failed "
                 f"(the other {len(done)} are in {path}; run the same command again to retry them; no summary written):"]
        lines += [f"  seed {s}: {failed[s].splitlines()[0]}" for s in sorted(failed)[:10]]
        detail = failed[first].partition("\n")[2].rstrip()
        print("\n".join(lines + ([f"seed {first}:", detail] if detail else [])), file=sys.stderr)
        # every failure a refusal for a named reason: its exit code (2 a plan that failed its checks, 1 a plugin)
        return max(refused.values()) if len(refused) == len(failed) else 1
    rows = [done[s] for s in seeds]
    summary = {**session.describe(), "split": opts.split, "seeds": [seeds[0], seeds[-1]], **summarise(rows),
               "provenance": machine}
    write_json(path.with_suffix(".json"), summary)
    print(f"{session.task.name} / {session.method}: normalised improvement {summary['improvement_mean']:.3f} +/- "
          f"{summary['improvement_std']:.3f}, success {100 * summary['success_rate']:.0f}% over {len(rows)} configs "
          f"(planning {summary['plan_s_mean']:.1f} s, execution {summary['execute_s_mean']:.1f} s per episode)")
    return 0


def _settings(setup: Any) -> Any:
    """What must match for a result file to be resumed: the resolved run config without its seed."""
    config = dict((setup or {}).get("config") or {})
    for key in ("seed", "threads", "device"):  # none of them changes an episode's result
        config.pop(key, None)
    return config
