"""Re-make every row of the results tables with today's code, and compare with the rows in docs/results.

    python benchmarks/rerun_results.py list                        # every row, its command, its last run's time
    python benchmarks/rerun_results.py run OUT [--jobs 2] [--only GLOB ...]
    python benchmarks/rerun_results.py compare OUT                 # old against new; exit 1 when a row lost > 1
    python benchmarks/rerun_results.py adopt OUT                   # the finished rows into docs/results + tables

For a change that moves the simulator's floats (docs/simulator.md, "Benchmark"): every row the tables cite
(:func:`results_table.rows`) is made again by the command that made it, into OUT. ``run`` is resumable: a row
whose summary is in OUT is skipped, and ``pasta eval`` resumes a half-written row episode by episode, so the same
command continues after an interruption. ``--jobs`` rows run at once, each on one thread (``threads=1``), with
their output in OUT/logs; the commands run in this checkout, so its code makes the rows (run the script of the
checkout under test). ``compare`` prints, per row, the successes and mean normalised improvement before and
after, and exits 1 when a row lost more than one success (the bar a simulator change must pass, issue 44); rows
not made yet are counted, not compared.
"""

from __future__ import annotations

import argparse
import fnmatch
import json
import shutil
import subprocess
import sys
import time
from pathlib import Path
from typing import IO

from results_table import PLUGIN, RESULTS, ROOT, Row, _rows, rows

#: where a row's command writes its output inside OUT (SAC-Point trains into a folder of its own)
LOGS = "logs"


def summary(folder: Path, row: Row) -> dict | None:
    """The row's finished summary in ``folder`` (None while it is missing or holds fewer episodes)."""
    path = folder / f"{row.name}.json"
    if not path.exists():
        return None
    data = json.loads(path.read_text())
    return data if data.get("episodes") == row.configs else None


def last_seconds(row: Row) -> float | None:
    """Wall seconds of the row's episodes in docs/results (None when they were not recorded)."""
    if not (RESULTS / f"{row.name}.jsonl").exists():
        return None
    seconds = [episode.get("wall_s") for episode in _rows(RESULTS, row.name)]
    return float(sum(seconds)) if seconds and all(s is not None for s in seconds) else None


def command(row: Row, out: Path) -> list[str]:
    """The command that makes ``row`` into ``out``, with this interpreter."""
    if row.script:
        return [sys.executable, str(ROOT / row.script), *row.settings, "--threads", "1",
                "--out", str(out / "sac" / row.name)]
    return [sys.executable, "-m", "pasta", "eval", *row.settings, "threads=1", f"out={out}"]


def collect(row: Row, out: Path) -> None:
    """A script row's own files (``result.json``, ``episodes.jsonl``) under the name the tables cite."""
    if row.script:
        folder = out / "sac" / row.name
        shutil.copyfile(folder / "result.json", out / f"{row.name}.json")
        shutil.copyfile(folder / "episodes.jsonl", out / f"{row.name}.jsonl")


def checkout_commit() -> str:
    """The commit of the checkout that makes the rows, with ``+changes`` when its tree differs from it. (Not
    ``pasta.io.provenance``'s commit: that is of the pasta this process imports, which may be another checkout's
    editable install.)"""
    try:
        head = subprocess.run(["git", "rev-parse", "--short=12", "HEAD"], cwd=ROOT, capture_output=True, text=True,
                              check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=ROOT, capture_output=True,
                               text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown (not a git checkout)"
    return head + ("+changes" if dirty else "")


def missing_plugin(row: Row) -> str:
    """Why ``row`` cannot run in this environment (its skill plugin is not installed), or empty."""
    if not row.needs:
        return ""
    from pasta.plugins import get_plugins

    if row.needs in get_plugins().skills:
        return ""
    return f"needs the `{row.needs}` skill: pip install -e examples/{PLUGIN[0]}"


def select(patterns: list[str] | None) -> list[Row]:
    chosen = [row for row in rows() if not patterns or any(fnmatch.fnmatch(row.name, p) for p in patterns)]
    if patterns and not chosen:
        raise SystemExit(f"--only {' '.join(patterns)}: no row matches (see `list`)")
    return chosen


def cmd_list(args: argparse.Namespace) -> int:
    total = 0.0
    print("| row | configs | command | last run, min |")
    print("|---|---:|---|---:|")
    for row in select(args.only):
        seconds = last_seconds(row)
        total += seconds or 0.0
        shown = " ".join([row.script or "pasta eval", *row.settings])
        print(f"| {row.name} | {row.configs} | `{shown}` | {'?' if seconds is None else f'{seconds / 60:.0f}'} |")
    print(f"\nrecorded wall time of these rows, one at a time: {total / 3600:.1f} h")
    return 0


def cmd_run(args: argparse.Namespace) -> int:
    out = args.out.resolve()
    (out / LOGS).mkdir(parents=True, exist_ok=True)
    print(f"rows made by the pasta of {ROOT} (the commands run there: its checkout is imported first), "
          f"commit {checkout_commit()}", flush=True)
    todo = []
    for row in select(args.only):
        why = missing_plugin(row)
        if summary(out, row) is not None:
            print(f"done already: {row.name}")
        elif why:
            print(f"left out: {row.name} ({why})")
        else:
            todo.append(row)
    expected = {row.name: last_seconds(row) for row in todo}  # None: no record (SAC-Point's training)
    running: dict[str, tuple[subprocess.Popen, float, Row, IO[bytes]]] = {}
    failed: list[str] = []
    done_old = done_new = 0.0
    start = time.monotonic()
    queue = list(todo)
    while queue or running:
        while queue and len(running) < args.jobs:
            row = queue.pop(0)
            log = (out / LOGS / f"{row.name}.log").open("ab")
            running[row.name] = (subprocess.Popen(command(row, out), cwd=ROOT, stdout=log, stderr=subprocess.STDOUT),
                                 time.monotonic(), row, log)
            print(f"started {row.name}", flush=True)
        time.sleep(args.poll)
        for name, (proc, began, row, log) in list(running.items()):
            if proc.poll() is None:
                continue
            del running[name]
            log.close()
            if proc.returncode == 0:
                collect(row, out)
            made = summary(out, row)
            if proc.returncode != 0 or made is None:
                failed.append(name)
                print(f"FAILED {name} (exit {proc.returncode}; log {out / LOGS / (name + '.log')})", flush=True)
                continue
            if expected[name]:
                done_old += expected[name]
                done_new += time.monotonic() - began
            print(f"finished {name}: {successes(made)}/{made['episodes']} successes, "
                  f"{(time.monotonic() - began) / 60:.1f} min; {len(todo) - len(queue) - len(running) - len(failed)}"
                  f"/{len(todo)} rows, {(time.monotonic() - start) / 60:.0f} min so far"
                  + eta([*queue, *(r for _, _, r, _ in running.values())], expected, done_new / done_old if done_old else 1.0,
                        args.jobs), flush=True)
    if failed:
        print(f"{len(failed)} rows failed: {', '.join(failed)} (the same command resumes them)")
    return 1 if failed else 0


def eta(left: list[Row], expected: dict[str, float | None], pace: float, jobs: int) -> str:
    """``, about N min left``: the rows left at their last run's time times the pace so far (new / last), plus
    the rows with no recorded time."""
    known = sum(expected[row.name] or 0.0 for row in left) * pace / jobs
    unknown = sum(expected[row.name] is None for row in left)
    return f", about {known / 60:.0f} min left" + (f" + {unknown} rows of unrecorded length" if unknown else "")


def successes(data: dict) -> int:
    return round(data["success_rate"] * data["episodes"])


def compare(out: Path, chosen: list[Row]) -> tuple[list[str], list[str], int]:
    """The comparison table's lines, the rows that lost more than one success, and how many are not made yet."""
    lines = ["| row | successes, docs/results | successes, new | change | improvement, docs/results | "
             "improvement, new |", "|---|---:|---:|---:|---:|---:|"]
    lost, pending = [], 0
    for row in chosen:
        old, new = summary(RESULTS, row), summary(out, row)
        if new is None:
            pending += 1
            continue
        if old is None:
            lines.append(f"| {row.name} | not run | {successes(new)}/{row.configs} | | | "
                         f"{new['improvement_mean']:.3f} |")
            continue
        change = successes(new) - successes(old)
        if change < -1:
            lost.append(row.name)
        lines.append(f"| {row.name} | {successes(old)}/{row.configs} | {successes(new)}/{row.configs} | "
                     f"{change:+d}{' **lost more than one**' if change < -1 else ''} | "
                     f"{old['improvement_mean']:.3f} | {new['improvement_mean']:.3f} |")
    return lines, lost, pending


def cmd_compare(args: argparse.Namespace) -> int:
    lines, lost, pending = compare(args.out, select(args.only))
    print("\n".join(lines))
    print(f"\n{len(lines) - 2} rows compared, {pending} not made yet; "
          + (f"{len(lost)} lost more than one success: {', '.join(lost)}" if lost else
             "none lost more than one success"))
    return 1 if lost else 0


def cmd_adopt(args: argparse.Namespace) -> int:
    import results_table

    copied = 0
    for row in select(args.only):
        if summary(args.out, row) is None:
            continue
        for suffix in (".json", ".jsonl"):
            shutil.copyfile(args.out / f"{row.name}{suffix}", RESULTS / f"{row.name}{suffix}")
        copied += 1
    print(f"{copied} rows copied into {RESULTS}")
    return results_table.main(["--write"])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="command", required=True)
    for name, helptext in (("list", "every row and its command"), ("run", "make the rows into OUT"),
                           ("compare", "OUT's rows against docs/results"),
                           ("adopt", "copy OUT's finished rows into docs/results and rewrite the tables")):
        p = sub.add_parser(name, help=helptext)
        if name != "list":
            p.add_argument("out", type=Path, help="folder for the new rows")
        p.add_argument("--only", nargs="+", metavar="GLOB", help="rows whose name matches (e.g. 'crs_twice_*')")
        if name == "run":
            p.add_argument("--jobs", type=int, default=2, help="rows at once, one thread each")
            p.add_argument("--poll", type=float, default=5.0, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    return {"list": cmd_list, "run": cmd_run, "compare": cmd_compare, "adopt": cmd_adopt}[args.command](args)


if __name__ == "__main__":
    sys.exit(main())
