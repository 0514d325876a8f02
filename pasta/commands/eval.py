"""``pasta eval task=T method=M num=20``: a method's normalised improvement and success on a task's fixed test set.

Episodes run on the task's fixed test seeds (``pasta.tasks.fixed_test_seeds``: 1000, 1001, ...), or with
``split=val`` on its validation seeds (2000, 2001, ...: choose settings there, report the test seeds). Every
finished episode is appended to ``OUT/<task>_<method>[_h<H>][_learned][_val].jsonl`` at once, so an
interrupted evaluation resumes where it stopped (``resume=false`` starts over); the summary (mean +/- std
of the normalised improvement, success rate, planning and execution seconds) is printed and written
next to it as ``.json``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pasta.core.errors import ConfigError, did_you_mean

HELP = "evaluate a method on a task's fixed test set (task=T method=pasta|sampling|flat|oracle num=20)"

EPILOG = """examples:
  pasta eval task=crs method=pasta num=20
  pasta eval task=crs method=flat num=20
  pasta eval task=crs_twice method=pasta num=20          # receding horizon with the given skeleton, as in the paper
  pasta eval task=crs method=pasta horizon=5 num=20      # a longer planning horizon than the task needs
  pasta eval task=cut_rearrange method=oracle num=20
  pasta eval task=crs method=pasta skills=cut,push,roll   # plan with these skills only
  pasta eval task=crs_distractors num=10 task.distractors=4   # a task setting -> crs_distractors_pasta_distractors4.jsonl
  pasta eval task=crs method=pasta workers=2              # two episodes at a time, in local worker processes
  pasta eval task=crs method=pasta backend=ray ray.address=auto   # episodes as Ray tasks on a cluster
keys: task method num split(test|val) out models controller horizon skeleton skills resume threads workers,
task.<setting> (a task config field: its own instances and result file, e.g. task.distractors=4),
backend(local|ray) ray.address ray.num_cpus, execute.<field>; other key=value items go to the run config (planner, planner.*, device). Without skills=,
skills with no trained weights under the models root are left out with a warning (as `pasta run`)."""


@dataclass
class EvalArgs:
    """The ``pasta eval`` keys (the rest go to the run config or ``execute.*``)."""

    task: str = "crs"
    method: str = "pasta"
    num: int = 20
    # "test": the fixed test seeds 1000, 1001, ... (report these); "val": 2000, 2001, ... (choose settings here)
    split: str = "test"
    out: str = "runs/eval"
    models: str = ""
    horizon: int = 0
    skeleton: str = "auto"
    # comma-separated skills to plan with; empty: every registered skill with trained weights
    skills: str = ""
    resume: bool = True
    # torch CPU threads (0: torch's default). 1 by default: crs planning took 5.6 s with 1 thread and
    # 126 s with 2 on a 2-core machine that was also running a training job.
    threads: int = 1
    # episodes at once: 0 runs them in this process; N in N local worker processes (backend=local) or at
    # most N Ray tasks in flight (backend=ray; 0: as many as the cluster has CPUs). docs/scaling.md
    workers: int = 0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = EPILOG
    parser.add_argument("overrides", nargs="*", metavar="key=value", help="task=NAME method=NAME num=20 ...")


def result_path(out: str | Path, task: str, method: str, horizon: int, controller: str, split: str = "test",
                skills: str = "", task_settings: dict[str, Any] | None = None) -> Path:
    """``OUT/<task>_<method>[_h<H>][_learned][_skills-a-b][_<setting><value>...][_val].jsonl`` (``_skills-...``
    when ``skills=`` is given, ``_distractors4`` for ``task.distractors=4``: other instances, another file)."""
    from pasta.execute.skillset import parse_skill_names

    name = f"{task}_{method}" + (f"_h{horizon}" if horizon else "") + ("_learned" if controller == "learned" else "")
    names = parse_skill_names(skills)
    name += f"_skills-{'-'.join(names)}" if names else ""
    for key, value in sorted((task_settings or {}).items()):
        name += f"_{key}{value}"
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
    from pasta.execute.session import build_session
    from pasta.io.provenance import provenance

    if setup["threads"] > 0:
        import torch

        torch.set_num_threads(setup["threads"])
    session = build_session(setup["task"], method=setup["method"], models=setup["models"] or None,
                            config_overrides=list(setup["config_overrides"]), execute=dict(setup["execute"]),
                            horizon=setup["horizon"] or None, skeleton=setup["skeleton"], skills=setup["skills"] or None,
                            task_settings=setup.get("task_settings"))
    sim = session.task.make_sim()  # it starts Taichi, whose settings the provenance records
    # versions, CPU, Taichi arch and compile options: results differ slightly between machines (docs/simulator.md)
    return EvalState(session, sim, provenance(sim_config=session.task.sim_config))


def eval_job(state: EvalState, seed: int, attempt: int) -> dict[str, Any]:
    """One episode's result row (the driver appends it to the result file)."""
    t0 = time.perf_counter()
    out = state.session.episode(seed, sim=state.sim)
    return {**out.to_dict(), "wall_s": round(time.perf_counter() - t0, 2), "setup": state.session.describe(),
            "provenance": state.machine}


def run(args: argparse.Namespace) -> int:
    from pasta.commands.run import print_skill_warning, split_overrides
    from pasta.config.overrides import build_many
    from pasta.distributed import BackendError, map_jobs, split_backend_args
    from pasta.tasks import fixed_test_seeds, fixed_val_seeds, split_task_settings

    task_settings, items = split_task_settings(list(args.overrides))
    backend, items = split_backend_args(items)
    backend.check()  # a missing Ray fails before any model is loaded
    own_run, execute_kw, rest = split_overrides(items)
    mine = [f"{k}={v}" for k, v in own_run.items()]
    passthrough = []
    fields = set(EvalArgs.__dataclass_fields__)
    for item in rest:
        (mine if item.partition("=")[0].strip() in fields else passthrough).append(item)
    from pasta.config import load_config

    top = set(load_config([]).keys())
    for item in passthrough:
        key = item.partition("=")[0].strip()
        if key.split(".")[0] not in top:
            raise ConfigError(f"unknown key '{key}'{did_you_mean(key, sorted(fields | top))}; "
                              f"pasta eval keys: {', '.join(sorted(fields))}, controller, execute.<field>")
    opts = build_many(mine, [EvalArgs], command="pasta eval")[0]
    if opts.num < 1:
        raise ConfigError(f"num must be >= 1, got {opts.num}")
    if opts.split not in ("test", "val"):
        raise ConfigError(f"split must be 'test' or 'val', got {opts.split!r}{did_you_mean(opts.split, ('test', 'val'))}")
    if any(i.partition("=")[0].strip() == "seed" for i in passthrough):
        raise ConfigError("pasta eval runs the fixed test seeds (1000, 1001, ...); use num=N, not seed=")
    from pasta.config.validate import check_int, check_output_dir, check_output_file, check_threads

    check_threads(opts.threads, "threads")
    check_int(opts.horizon, "horizon", low=0)
    check_output_dir(opts.out, "out")  # before any model is loaded: a bad out= must not cost an evaluation
    check_int(opts.workers, "workers", low=0)
    setup = {"task": opts.task, "method": opts.method, "models": opts.models, "config_overrides": list(passthrough),
             "execute": dict(execute_kw), "horizon": opts.horizon, "skeleton": opts.skeleton, "skills": opts.skills,
             "threads": opts.threads, "task_settings": dict(task_settings)}
    state = eval_init(setup)  # this process's session: the result path, the summary, the episodes with workers=0
    session, machine = state.session, state.machine
    print_skill_warning(session)
    path = result_path(opts.out, opts.task, opts.method, opts.horizon, session.exe.controller, opts.split, opts.skills,
                       {k: getattr(session.task.config, k) for k in task_settings})
    check_output_file(path, "out")  # e.g. a directory of the result file's name in out=
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
    elif path.exists():
        path.unlink()
    seeds = fixed_test_seeds(opts.num) if opts.split == "test" else fixed_val_seeds(opts.num)
    todo = [s for s in seeds if s not in done]
    print(f"eval {opts.task} / {opts.method}: {len(seeds)} {opts.split} configs, {len(seeds) - len(todo)} already in {path}",
          file=sys.stderr)
    where = "" if backend.name == "local" and not opts.workers else f" on {backend.describe()}" + (
        f" with {opts.workers} workers" if opts.workers else "")
    failed: dict[int, str] = {}
    try:
        for outcome in map_jobs(eval_init, eval_job, setup, todo, backend=backend, workers=opts.workers,
                                label="episode", prog="pasta eval", state=state):
            seed = int(outcome.item)
            if not outcome.ok:
                failed[seed] = outcome.error or ""
                print(f"[{len(done) + len(failed)}/{len(seeds)}] seed {seed}: failed, {failed[seed].splitlines()[0]}",
                      file=sys.stderr, flush=True)
                continue
            row = outcome.value
            with path.open("a") as f:  # one line per finished episode, by this process only: nothing is lost on interruption
                f.write(json.dumps(row) + "\n")
            done[seed] = row
            skel = "-".join(row.get("skeleton", [])) or "ground truth"
            print(f"[{len(done) + len(failed)}/{len(seeds)}] seed {seed}: {skel:<24} improvement {row['improvement']:+.3f} "
                  f"{'success' if row['success'] else 'failure'}  (plan {row['plan_s']:.1f} s, execute {row['execute_s']:.1f} s)"
                  f"{where}", file=sys.stderr, flush=True)
    except BackendError as exc:  # workers could not start, or the cluster is unreachable: not a usage error
        print(f"pasta eval: error: {exc} ({len(done)} of {len(seeds)} episodes are in {path}; "
              "run the same command again to continue)", file=sys.stderr)
        return 1
    if failed:
        first = min(failed)
        lines = [f"pasta eval: error: {len(failed)} of {len(seeds)} episodes of {opts.task} / {opts.method} failed "
                 f"(the other {len(done)} are in {path}; run the same command again to retry them; no summary written):"]
        lines += [f"  seed {s}: {failed[s].splitlines()[0]}" for s in sorted(failed)[:10]]
        detail = failed[first].partition("\n")[2].rstrip()
        print("\n".join(lines + ([f"seed {first}:", detail] if detail else [])), file=sys.stderr)
        return 1
    rows = [done[s] for s in seeds]
    summary = {**session.describe(), "split": opts.split, "seeds": [seeds[0], seeds[-1]], **summarise(rows),
               "provenance": machine}
    path.with_suffix(".json").write_text(json.dumps(summary, indent=2) + "\n")
    print(f"{opts.task} / {opts.method}: normalised improvement {summary['improvement_mean']:.3f} +/- "
          f"{summary['improvement_std']:.3f}, success {100 * summary['success_rate']:.0f}% over {len(rows)} configs "
          f"(planning {summary['plan_s_mean']:.1f} s, execution {summary['execute_s_mean']:.1f} s per episode)")
    return 0
