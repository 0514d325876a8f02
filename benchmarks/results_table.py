"""The results tables, generated from the ``pasta eval`` summaries in docs/results (markdown).

    python benchmarks/results_table.py                       # print them (from docs/results)
    python benchmarks/results_table.py --write               # replace them in their files, between the markers

Two blocks, each between its markers in one file (:data:`BLOCKS`): ``results`` (README.md: per task, the paper's
ablations and baselines, the closed loop under disturbance) and ``plugin`` (docs/planning.md: every task with the
example third-party plugin installed). Every row is one
``pasta eval ... num=20`` on the fixed test configs (seeds 1000-1019), whose summary ``<file>.json`` lies in
docs/results with its per-episode rows ``<file>.jsonl`` (the file names are the ones ``pasta eval`` writes for the
settings given). tests/test_readme_results.py checks that the files hold exactly what this prints, so the docs
cannot drift from the results they cite.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import NamedTuple

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "docs" / "results"


def markers(block: str) -> tuple[str, str]:
    """The start and end markers of ``block`` in the file that shows it."""
    return f"<!-- {block}:start (python benchmarks/results_table.py) -->", f"<!-- {block}:end -->"


START, END = markers("results")

#: (task, the paper's PASTA result: normalised improvement and success on its 5 configs, its planning seconds)
TASKS = (
    ("lift_spread", (0.904, 1.00), None),
    ("gather_move", (0.715, 1.00), None),
    ("cut_rearrange", (0.837, 0.80), 35.0),
    ("crs", (0.896, 1.00), 307.0),
    ("crs_twice", (0.604, 0.40), 7810.0),
    ("crs_distractors", None, None),
)

#: the paper's ablations and baselines we ran: (task, what, file under docs/results, the command's settings, paper)
ABLATIONS = (
    ("cut_rearrange", "PASTA, cut and push only", "cut_rearrange_pasta_skills-cut-push", "skills=cut,push", None),
    ("cut_rearrange", "no hard negatives (cut and push feasibility trained without them)",
     "cut_rearrange_pasta_models-no-hard-negatives_skills-cut-push",
     "skills=cut,push models=pasta/weights/ablations/no_hard_negatives", None),
    ("cut_rearrange", "no sampling (one initialisation per attention structure)",
     "cut_rearrange_pasta_attention-enumerate_num_samples-1_refine_sequences-0",
     "planner.attention=enumerate planner.num_samples=1 planner.refine_sequences=0", None),
    ("cut_rearrange", "no gradient (cross-entropy method, 1,024 samples per sequence)", "cut_rearrange_pasta_planner-sampling",
     "planner=sampling", None),
    ("crs", "Flat 3D (the whole scene as one latent)", "crs_flat", "method=flat", (-0.712, 0.00)),
    ("lift_spread", "SAC-Point (model-free RL, Stable-Baselines3, 50,000 env steps)", "lift_spread_sac-point",
     "scripts/train_sac.py --task lift_spread --steps 50000", None),
    ("crs", "SAC-Point (model-free RL, Stable-Baselines3, 50,000 env steps)", "crs_sac-point",
     "scripts/train_sac.py --task crs --steps 50000", (0.573, 0.00)),
)

#: methods that plan nothing and load no pasta weights: their rows have no skill set or weights to check
NOT_PLANNED = ("oracle", "flat", "sac-point", "trajopt")

#: the Traj-Opt baseline (``pasta eval task=T method=trajopt num=5``): per task, the paper's Traj-Opt row (Table 1)
TRAJOPT = (("lift_spread", (0.818, 0.40)), ("gather_move", (0.403, 0.00)), ("cut_rearrange", (0.511, 0.20)),
           ("crs", (0.312, 0.00)), ("crs_twice", (0.227, 0.00)))
#: its test configs (seeds 1000-1004): a gradient costs ~5 minutes an episode on 2 cores (docs/simulator.md)
TRAJOPT_CONFIGS = 5


#: the closed loop under disturbance (docs/policies.md): these tasks, each disturbance kind ("": none)
LOOP_TASKS = ("crs", "cut_rearrange")
DISTURBANCES = ("", "shift", "split", "merge", "lump", "noise")


def result_name(task: str, *parts: str) -> str:
    """The name ``pasta eval`` gives the PASTA row of ``task`` with these settings' parts: sorted, ``_``-joined
    (``learned`` for ``execute.controller=learned``; pasta.commands.eval.result_path)."""
    return f"{task}_pasta" + "".join(f"_{part}" for part in sorted(parts))


def loop_name(task: str, kind: str, *, learned: bool, closed: bool) -> str:
    """The ``pasta eval`` result name of ``task`` under disturbance ``kind``, open or closed loop."""
    return result_name(task, *(["learned"] if learned else []), *([f"disturb-{kind}"] if kind else []),
                       *(["loop-closed"] if closed else []))


def loop_names() -> list[str]:
    return [loop_name(task, kind, learned=learned, closed=closed) for task in LOOP_TASKS for kind in DISTURBANCES
            for learned in (False, True) for closed in (False, True)]


def _summary(results: Path, name: str) -> dict | None:
    """The summary ``name.json`` with ``executed_skills`` (the skills of the steps its episodes, ``name.jsonl``,
    executed; absent without that file)."""
    path = results / f"{name}.json"
    if not path.exists():
        return None
    summary = json.loads(path.read_text())
    episodes = path.with_suffix(".jsonl")
    if episodes.exists():
        summary["executed_skills"] = sorted({step["skill"] for line in episodes.read_text().splitlines() if line.strip()
                                             for step in json.loads(line).get("steps") or []})
    return summary


#: the mark of a row made by an earlier pasta: planned with a skill its task's scene does not allow (before the scene
#: check), or with weights other than the shipped ones (before the cost model learned height)
OUTSIDE_SCENE = "†"


def _cell(summary: dict | None) -> str:
    if summary is None:
        return "not run"
    return (f"{summary['improvement_mean']:.3f} ± {summary['improvement_std']:.3f} / "
            f"{100 * summary['success_rate']:.0f}%" + (OUTSIDE_SCENE if stale(summary) else ""))


def stale(summary: dict) -> list[str]:
    """Why ``summary`` is not what the current pasta makes: ``scene`` (:func:`outside_scene`), ``weights``
    (:func:`other_weights`); empty when it is current."""
    return [why for why, found in (("scene", outside_scene(summary)), ("weights", other_weights(summary))) if found]


def other_weights(summary: dict) -> list[str]:
    """The checkpoints ``summary``'s row was made with that differ from those its settings load now (digests of
    ``model.safetensors``); ``["unrecorded"]`` for a row made before rows recorded their weights (2026-12-05, when the
    shipped cost model was retrained). A skill's policy counts only where the row executed that skill
    (``executed_skills``, when known): a policy that never acted leaves the row as it is. Rows of :data:`NOT_PLANNED` methods are left out (the scene-level models did not change; SAC has its own)."""
    from pasta.io.checkpoint import weights_digest
    from pasta.weights import ROOT as SHIPPED
    from pasta.weights import module_dir

    if summary.get("method") in NOT_PLANNED:
        return []
    recorded = summary.get("weights")
    if not recorded:
        return ["unrecorded"]
    config = summary["config"]

    def local(path: str) -> Path:  # a path of the machine that made the row, under this checkout's shipped weights
        marker = "pasta/weights/"
        text = str(path)
        if marker in text and not Path(text).exists():
            return SHIPPED / text.split(marker, 1)[1]
        return Path(text) if Path(text).is_absolute() else ROOT / text  # relative: to the checkout

    root = local(config.get("models") or str(SHIPPED))
    where = {"encoder": local(config["encoder"]["weights"]), "cost": local(config["cost_model"]["weights"])}
    executed = summary.get("executed_skills")
    if executed is not None:
        recorded = {name: digest for name, digest in recorded.items()
                    if not name.startswith("policy/") or name.split("/", 1)[1] in executed}
    return sorted(name for name, digest in recorded.items()
                  if weights_digest(where.get(name, module_dir(root, name))) != digest)


def outside_scene(summary: dict) -> list[str]:
    """The skills of ``summary``'s recorded skill set that its task's scene does not allow (pasta.tasks.scene): a
    row run before pasta fitted the skills to the scene, to be re-run."""
    from pasta.plugins import get_plugins
    from pasta.tasks import get_task
    from pasta.tasks.scene import floor_height, resolve_scene, scene_fit

    if not summary.get("skills"):  # a method that plans no skills (SAC-Point)
        return []
    task = get_task(summary["task"])
    scene = resolve_scene(task.scene(), floor_height(int(summary["config"]["sim"]["n_grid"])))
    registered = get_plugins().skills  # a plugin's skill is checked where the plugin is installed
    return sorted(scene_fit([name for name in summary.get("skills") or [] if name in registered], scene))


def _paper(paper: tuple[float, float] | None) -> str:
    return "" if paper is None else f"{paper[0]:.3f} / {100 * paper[1]:.0f}%"


def _check(summary: dict | None, name: str, configs: int = 20) -> None:
    """A row must be the fixed test set, ``configs`` configs."""
    if summary is not None and (summary.get("split") != "test" or summary.get("episodes") != configs):
        raise SystemExit(f"{name}.json: not a {configs}-config test-set summary (split {summary.get('split')}, "
                         f"{summary.get('episodes')} episodes)")


def trajopt_names() -> list[str]:
    return [f"{task}_trajopt" for task, _ in TRAJOPT]


def table(results: Path = RESULTS) -> str:
    """The README's block: per task (heuristic, learned, paper), the paper's ablations and baselines, then the
    closed loop under disturbance (open and closed, heuristic and learned)."""
    lines = ["| task | PASTA, heuristic controllers | PASTA, learned policies | paper (PASTA) | plan s, ours / paper |",
             "|---|---:|---:|---:|---:|"]
    for task, paper, paper_s in TASKS:
        heuristic, learned = _summary(results, f"{task}_pasta"), _summary(results, f"{task}_pasta_learned")
        _check(heuristic, f"{task}_pasta")
        _check(learned, f"{task}_pasta_learned")
        ours_s = f"{heuristic['plan_s_mean']:.1f}" if heuristic else ""
        plan_s = ours_s + (f" / {paper_s:,.0f}" if paper_s else "")
        lines.append(f"| {task} | {_cell(heuristic)} | {_cell(learned)} | {_paper(paper)} | {plan_s} |")
    lines += ["", "| task | ablation or baseline (PASTA rows: heuristic controllers) | ours | paper | settings |",
              "|---|---|---:|---:|---|"]
    for task, what, name, settings, paper in ABLATIONS:
        summary = _summary(results, name)
        _check(summary, name)
        lines.append(f"| {task} | {what} | {_cell(summary)} | {_paper(paper)} | `{settings}` |")
    for (task, paper), name in zip(TRAJOPT, trajopt_names()):
        summary = _summary(results, name)
        _check(summary, name, TRAJOPT_CONFIGS)
        cost = ""
        if summary:
            minutes = (summary["plan_s_mean"] + summary["execute_s_mean"]) / 60
            cost = f", {summary['config']['trajopt']['iterations']} Adam iterations, {minutes:.1f} min an episode"
        lines.append(f"| {task} | Traj-Opt (gradient descent through the simulator, {TRAJOPT_CONFIGS} configs{cost}) | "
                     f"{_cell(summary)} | {_paper(paper)} | `method=trajopt num={TRAJOPT_CONFIGS}` |")
    lines += ["", "| task | disturbance | open loop, heuristic | closed loop, heuristic | open loop, learned | "
              "closed loop, learned |", "|---|---|---:|---:|---:|---:|"]
    for task in LOOP_TASKS:
        for kind in DISTURBANCES:
            cells = []
            for learned in (False, True):
                for closed in (False, True):
                    name = loop_name(task, kind, learned=learned, closed=closed)
                    summary = _summary(results, name)
                    _check(summary, name)
                    cells.append(_cell(summary))
            lines.append(f"| {task} | {kind or 'none'} | {cells[0]} | {cells[1]} | {cells[2]} | {cells[3]} |")
    lines += ["", "Normalised improvement (mean ± std) / success rate on the 20 fixed test configs (seeds 1000-1019); "
              "settings chosen on the validation configs (seeds 2000-2019). The paper evaluated 5 configs per task on "
              "a GPU. Each row is `pasta eval task=T num=20` with the settings named (learned policies: "
              "`execute.controller=learned`; under a disturbance: `disturb=KIND`, closed loop: `execute.loop=closed`); "
              "its per-episode rows are in `docs/results/` (SAC-Point: the script trains, then scores its policy on the "
              "same 20 configs; docs/gymnasium.md). Traj-Opt: `pasta eval task=T method=trajopt num=5`, gradient "
              "descent on the ground-truth tool chain's actions through the simulator, on the first 5 test configs "
              "(docs/simulator.md, \"Traj-Opt\"). Plan s: mean planning seconds per episode on one CPU "
              "thread, as each row's run measured it, on a 2-core machine that up to four runs shared "
              "(`benchmarks/bench_planner.py` times the planner alone)."]
    return _footnoted(lines)


#: the example third-party plugin package, its skill, and the models root (in the checkout) that holds its trained
#: networks only: the other skills, the VAE and the cost come from the shipped weights (pasta.weights.module_dir)
PLUGIN = ("pasta-pinch", "pinch", "examples/pasta-pinch/pinch_weights")


def plugin_name(task: str, *, learned: bool) -> str:
    """The ``pasta eval`` result name of ``task`` with the plugin's models root (``models=...``)."""
    return result_name(task, *(["learned"] if learned else []), f"models-{Path(PLUGIN[2]).name.replace('_', '-')}")


def plugin_names() -> list[str]:
    return [plugin_name(task, learned=learned) for task, _, _ in TASKS for learned in (False, True)]


def plugin_table(results: Path = RESULTS) -> str:
    """docs/planning.md's block: every task with and without the example plugin installed (its skill a candidate
    in every plan), and how many episodes planned it."""
    package, skill, root = PLUGIN
    lines = [f"| task | heuristic | + {package} | learned | + {package} | episodes planning {skill} |",
             "|---|---:|---:|---:|---:|---:|"]
    for task, _, _ in TASKS:
        cells, used = [], []
        for learned in (False, True):
            shipped = _summary(results, f"{task}_pasta" + ("_learned" if learned else ""))
            name = plugin_name(task, learned=learned)
            summary = _summary(results, name)
            _check(summary, name)
            cells += [_cell(shipped), _plugin_cell(summary)]
            used.append("-" if summary is None else str(sum(skill in row["skeleton"] for row in _rows(results, name))))
        lines.append(f"| {task} | {' | '.join(cells)} | {'not run' if set(used) == {'-'} else ' / '.join(used)} |")
    lines += ["", f"`pip install -e examples/{package}`, then `pasta eval task=T num=20 models={root}` (learned: "
              f"`execute.controller=learned`): that root holds only the plugin's trained networks (its feasibility "
              f"and policy), everything else comes from the shipped weights. Episodes planning {skill}: heuristic / "
              "learned."]
    return _footnoted(lines)


def _plugin_cell(summary: dict | None) -> str:
    """A row of the plugin table: stale only through the scene or the shipped weights (its own are the plugin's)."""
    if summary is None:
        return "not run"
    skill = PLUGIN[1]
    weights = {k: v for k, v in (summary.get("weights") or {}).items() if not k.endswith(f"/{skill}")}
    own = {**summary, "weights": weights or None}
    return _cell(own)


def _rows(results: Path, name: str) -> list[dict]:
    return [json.loads(line) for line in (results / f"{name}.jsonl").read_text().splitlines() if line.strip()]


def _footnoted(lines: list[str]) -> str:
    if any(OUTSIDE_SCENE in line for line in lines):
        lines += ["", f"{OUTSIDE_SCENE} Made by an earlier pasta, to be re-run: with networks other than the shipped "
                  "ones (the row's `weights` digests), or with a skill among the candidates that the task's scene now "
                  "leaves out (docs/planning.md, \"The scene\")."]
    return "\n".join(lines) + "\n"


class Row(NamedTuple):
    """One row the tables cite: the file stem under docs/results and the command that makes it."""

    name: str
    #: ``pasta eval`` settings (``task=crs num=20 ...``), or the arguments of ``script``
    settings: tuple[str, ...]
    configs: int = 20
    #: a script that makes the row instead of ``pasta eval`` (SAC-Point); empty for ``pasta eval``
    script: str = ""
    #: a skill that must be registered for the row (the example plugin's rows), else empty
    needs: str = ""


def rows() -> list[Row]:
    """Every row of every block (:data:`BLOCKS`), once each, in the order the tables show them."""
    found: dict[str, Row] = {}

    def add(row: Row) -> None:
        found.setdefault(row.name, row)

    def learned(flag: bool) -> tuple[str, ...]:
        return ("execute.controller=learned",) if flag else ()

    for task, _, _ in TASKS:
        for flag in (False, True):
            add(Row(result_name(task, *(["learned"] if flag else [])), (f"task={task}", "num=20", *learned(flag))))
    for task, _, name, settings, _ in ABLATIONS:
        words = tuple(settings.split())
        if words[0].endswith(".py"):
            add(Row(name, words[1:], script=words[0]))
        else:
            add(Row(name, (f"task={task}", "num=20", *words)))
    for (task, _), name in zip(TRAJOPT, trajopt_names()):
        add(Row(name, (f"task={task}", "method=trajopt", f"num={TRAJOPT_CONFIGS}"), configs=TRAJOPT_CONFIGS))
    for task in LOOP_TASKS:
        for kind in DISTURBANCES:
            for flag in (False, True):
                for closed in (False, True):
                    add(Row(loop_name(task, kind, learned=flag, closed=closed),
                            (f"task={task}", "num=20", *learned(flag), *([f"disturb={kind}"] if kind else []),
                             *(["execute.loop=closed"] if closed else []))))
    for task, _, _ in TASKS:
        for flag in (False, True):
            add(Row(plugin_name(task, learned=flag), (f"task={task}", "num=20", *learned(flag), f"models={PLUGIN[2]}"),
                    needs=PLUGIN[1]))
    return list(found.values())


#: each block: the file that shows it (relative to the checkout) and what prints it
BLOCKS = {"results": ("README.md", table), "plugin": ("docs/planning.md", plugin_table)}


def shown(block: str) -> str:
    """What ``block``'s file holds between its markers now."""
    start, end = markers(block)
    text = (ROOT / BLOCKS[block][0]).read_text()
    if start not in text or end not in text:
        raise SystemExit(f"{BLOCKS[block][0]} has no {start} ... {end} markers")
    return text.split(start, 1)[1].split(end, 1)[0].lstrip("\n")


def replace_in(text: str, body: str, block: str = "results") -> str:
    """``text`` with everything between ``block``'s markers replaced by ``body``."""
    start, end = markers(block)
    if start not in text or end not in text:
        raise SystemExit(f"the file has no {start} ... {end} markers")
    head, _, rest = text.partition(start)
    _, _, tail = rest.partition(end)
    return f"{head}{start}\n{body}{end}{tail}"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("results", nargs="?", type=Path, default=RESULTS, help="folder of pasta eval summaries")
    ap.add_argument("--write", action="store_true",
                    help="replace every block between its markers in its file (" + ", ".join(
                        f"{block}: {file}" for block, (file, _) in BLOCKS.items()) + ")")
    args = ap.parse_args(argv)
    bodies = {block: make(args.results) for block, (_, make) in BLOCKS.items()}
    for block, (file, _) in BLOCKS.items() if args.write else ():
        path = ROOT / file
        path.write_text(replace_in(path.read_text(), bodies[block], block))
    if not args.write:
        sys.stdout.write("\n".join(f"{markers(block)[0]}\n{body}" for block, body in bodies.items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
