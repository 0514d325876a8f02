"""Print the results table of `pasta eval` summaries beside the paper's numbers (markdown).

    python benchmarks/results_table.py [runs/eval] [--val]

Reads every ``<task>_<method>[_h<H>].json`` that ``pasta eval`` wrote (test split; validation
summaries, ``*_val.json``, only with ``--val``) and prints one row per
(task, method) with the normalised improvement (mean +/- std), the success rate, the number of test
configs and the mean planning / execution seconds per episode, next to the paper's figure where it
reported one (PASTA, CoRL 2022, Table 1 and the planning times of Section 5).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

#: (task, method) -> (normalised improvement, success rate) reported by the paper (5 configs each)
PAPER = {
    ("cut_rearrange", "pasta"): (0.837, 0.80),
    ("crs", "pasta"): (0.896, 1.00),
    ("crs_twice", "pasta"): (0.604, 0.40),
    ("cut_rearrange", "flat"): (0.797, 0.60),
    ("crs", "flat"): (-0.712, 0.00),
    ("lift_spread", "pasta"): (0.904, 1.00),
    ("gather_move", "pasta"): (0.715, 1.00),
}
#: task -> planning seconds per episode in the paper (on a GPU)
PAPER_PLAN_S = {"cut_rearrange": 35.0, "crs": 307.0, "crs_twice": 7810.0}
TASKS = ("lift_spread", "gather_move", "cut_rearrange", "crs", "crs_twice", "crs_distractors")
METHODS = ("pasta", "sampling", "flat", "oracle")
#: the planner a method uses unless the run names another (pasta.execute.session.build_session)
DEFAULT_PLANNER = {"pasta": "exhaustive", "sampling": "sampling", "flat": "exhaustive"}


def default_planner(task: str, method: str) -> str | None:
    if method in ("pasta", "flat") and task == "crs_twice":
        return "receding_horizon"
    return DEFAULT_PLANNER.get(method)


def setting_changes(summary: dict) -> str:
    """``"distractors=4"`` for a run with task settings (``task.<setting>=``) other than the task's defaults
    (from the summary's ``task_config``; runs before it was recorded have none)."""
    given = summary.get("task_config") or {}
    if not given:
        return ""
    from dataclasses import asdict

    from pasta.tasks import get_task

    return changed_keys(given, asdict(get_task(summary["task"]).config))


def changed_keys(given: dict, default: dict, skip: set[str] | frozenset[str] = frozenset()) -> str:
    """``"k=v, ..."`` for the keys of ``given`` that ``default`` has, outside ``skip``, with another value."""
    return ", ".join(f"{k}={v}" for k, v in sorted(given.items()) if k in default and k not in skip and default[k] != v)


#: planner keys not labelled: the attention mode is the "no sampling" ablation's label (ablation_labels)
UNLABELLED_PLANNER_KEYS = ("name", "attention")


def planner_changes(summary: dict) -> str:
    """``"final=24"`` for a run whose planner settings differ from that planner's defaults (its registered
    config), so a tuned run does not read as the default one; runs that recorded no settings give ``""``."""
    settings = summary.get("planner_settings") or {}
    name = settings.get("name") or summary.get("planner")
    if not settings or not name:
        return ""
    from dataclasses import asdict, is_dataclass

    from pasta.plugins import get_plugins

    planners = get_plugins(report=False).planners
    if name not in planners:
        return ""
    default = planners.default_config(name)
    default = asdict(default) if is_dataclass(default) else {}
    skip = set(UNLABELLED_PLANNER_KEYS)
    if settings.get("attention") == "enumerate":  # labelled "no sampling" / "N draws per attention structure"
        skip |= {"num_samples", "refine_sequences"}
    return changed_keys(settings, default, skip)


#: execute keys with labels of their own (the controller, "regression stop off", the raw method's corrections)
OWN_LABEL_EXECUTE_KEYS = ("controller", "regress_stop", "goal_mass", "goal_anchor")


def execute_changes(summary: dict) -> str:
    """``"skip_threshold=0.001"`` for a run whose execution settings (``execute.<key>=``) differ from today's
    defaults, beside the keys labelled otherwise; runs that recorded no settings give ``""``."""
    settings = summary.get("execute_settings") or {}
    if not settings:
        return ""
    from dataclasses import asdict

    from pasta.execute import ExecuteConfig

    return changed_keys(settings, asdict(ExecuteConfig()), set(OWN_LABEL_EXECUTE_KEYS))


def ablation_labels(summary: dict) -> str:
    """The paper's ablations and the raw method, from what a summary recorded: feasibility networks trained
    without hard negatives, one initialisation per attention structure, the goal-cloud corrections off."""
    out = []
    trained = summary.get("feasibility_training") or {}
    if trained and all(t.get("hard_per_positive", 10) == 0 for t in trained.values()):
        out.append("no hard negatives")
    planner = summary.get("planner_settings") or {}
    if planner.get("attention") == "enumerate":
        draws = planner.get("num_samples")
        out.append("no sampling" if draws == 1 else f"{draws} draws per attention structure")
    exe = summary.get("execute_settings") or {}
    if summary.get("method") != "oracle" and exe.get("goal_mass") is False and exe.get("goal_anchor") is False:
        out.append("raw: goal corrections off")
    return "".join(f", {x}" for x in out)


def rows(directory: Path, split: str = "test") -> list[dict]:
    out = []
    for path in sorted(directory.glob("*.json")):
        s = json.loads(path.read_text())
        if "improvement_mean" in s and s.get("split", "test") == split:
            s["name"] = path.stem
            out.append(s)
    order = {t: i for i, t in enumerate(TASKS)}
    return sorted(out, key=lambda s: (order.get(s["task"], 99), METHODS.index(s["method"]) if s["method"] in METHODS else 99,
                                      s.get("horizon", 0)))


def main(argv: list[str]) -> int:
    split = "val" if "--val" in argv else "test"
    argv = [a for a in argv if a != "--val"]
    directory = Path(argv[0]) if argv else Path("runs/eval")
    print("| task | method | skills | horizon | configs | normalised improvement | success | paper | plan s | execute s |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for s in rows(directory, split):
        default_run = s["name"] == f"{s['task']}_{s['method']}"  # not a horizon sweep or learned-policy run
        changed = setting_changes(s)
        default_run = default_run and not changed
        paper = PAPER.get((s["task"], s["method"])) if default_run else None
        paper_txt = f"{paper[0]:.3f} / {100 * paper[1]:.0f}%" if paper else ""
        name = s["method"] + (" (learned)" if s.get("controller") == "learned" else "")
        if s.get("planner") and s["method"] != "oracle" and s["planner"] != default_planner(s["task"], s["method"]):
            name += f", planner {s['planner']}"  # a run with planner=NAME other than the method's default
        if s["task"] == "crs_twice" and s["method"] != "oracle" and s.get("skeleton_given") is False:
            name += ", no skeleton"  # the skeleton is given for crs_twice by default, as in the paper
        if changed:
            name += f", {changed}"  # task.<setting>= (e.g. the distractor count)
        tuned = planner_changes(s)
        if tuned:
            name += f", {tuned}"  # planner.<key>= other than the planner's defaults (e.g. final=24)
        if s.get("controller") == "learned" and (s.get("execute_settings") or {}).get("regress_stop") == "off":
            name += ", regression stop off"  # execute.regress_stop=off: the learned policies' own stop only
        executed = execute_changes(s)
        if executed:
            name += f", {executed}"  # execute.<key>= other than the defaults (e.g. skip_threshold=0.001)
        name += ablation_labels(s)
        settings = s.get("planner_settings") or {}
        if s["method"] != "oracle" and "clearance_weight" not in settings:
            name += " (before clearance)"  # run before the clearance penalty and executor reorder existed
        elif s["method"] != "oracle" and "goal_mass" not in (s.get("execute_settings") or {}):
            name += " (before goal masses)"  # run before the executor's goal masses and anchor existed
        if (s.get("provenance") or {}).get("taichi", {}).get("fast_math", True):
            name += " †"  # run with Taichi fast_math on (every run before provenance was recorded)
        skills = len(s["skills"]) if s.get("skills") else ""  # the skills planned with (the search's width)
        print(f"| {s['task']} | {name} | {skills} | {s.get('horizon', '')} | {s['episodes']} | {s['improvement_mean']:.3f} ± "
              f"{s['improvement_std']:.3f} | {100 * s['success_rate']:.0f}% | {paper_txt} | {s['plan_s_mean']:.1f} | "
              f"{s['execute_s_mean']:.1f} |")
    print()
    print("skills: how many skills the planner chose from (3: cut, push, roll; 5: also lift and gather; blank: not "
          "recorded, and only cut, push and roll existed then).")
    print()
    print("† simulated with Taichi `fast_math` on (before issue 21 turned it off); instances and rollouts differ "
          "from today's by float rounding.")
    print()
    print("Paper planning time per episode (GPU): " + ", ".join(f"{t} {v:,.0f} s" for t, v in PAPER_PLAN_S.items()))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
