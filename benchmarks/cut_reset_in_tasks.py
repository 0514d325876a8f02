"""Where do learned cut reset poses put the knife inside a task, against the heuristic cut? Validation seeds.

Plans each episode of ``task`` on its validation seeds (2000, 2001, ...) with the shipped models, and at
the plan's first cut records the attended piece and the goal the executor hands the controller (a
recording controller stands in for the cut and ends the episode there). For each, every reset regressor in ``resets`` (policy directories holding
``reset.*``, e.g. ``pasta/weights/policy/cut``) places the knife (``ResetPose.tool_x``), and the row
compares its modelled cut plane (``CutSkill.reset_target``) with the heuristic's (``plan_from_goal``: the
split read from the goal pieces' point counts, the controller that succeeds on these configs). Where the
plan cuts the whole dough first and the task's own expert chain starts with a cut, each regressor is also
given the task's true state after that expert cut (``TaskInstance.step_goal(0)``) in place of the plan's
goal, and its plane is compared with that expert's (``true_*`` fields)::

    python benchmarks/cut_reset_in_tasks.py task=crs n=10 resets=pasta/weights/policy/cut,M/policy/cut [out=FILE.json]

Prints a line per episode (knife x, its phase in the grid cell, plane error in mm per regressor) and, per
regressor, the mean absolute plane error and how many cuts are more than 1 cm off (docs/policies.md,
"The cut's reset pose and the grid cell").
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import numpy as np


class _Recorded(Exception):
    """Raised by the recording controller once it has the first cut's piece and goal (ends the episode)."""

    def __init__(self, piece: np.ndarray, goal: np.ndarray) -> None:
        super().__init__("first cut recorded")
        self.piece, self.goal = piece, goal


class _Recorder:
    """A stand-in policy for the cut: its controller raises :class:`_Recorded` with the piece and goal."""

    def controller(self, skill: Any) -> Any:
        from pasta.core import Controller

        class _Record(Controller):
            def approach_pose(self, piece: np.ndarray, goal: np.ndarray | None, scene: np.ndarray | None = None) -> None:
                raise _Recorded(np.asarray(piece, np.float32).copy(), np.asarray(goal, np.float32).copy())

            def act(self, obs: Any) -> tuple[np.ndarray, bool]:  # never reached: approach_pose ends the episode
                raise RuntimeError("the recording controller does not act")

        return _Record()


def main(argv: list[str] | None = None) -> int:
    from pasta.config.overrides import script_args

    args = script_args(argv, __doc__, "python benchmarks/cut_reset_in_tasks.py")
    import torch

    torch.set_num_threads(int(args.get("threads", 1)))
    from pasta.execute.session import build_session
    from pasta.policy.reset import load_reset
    from pasta.tasks import fixed_val_seeds
    from pasta_skill_cut.skill import plan_from_goal

    task, n = args.get("task", "crs"), int(args.get("n", 10))
    dirs = [d for d in args.get("resets", "pasta/weights/policy/cut").split(",") if d]
    resets = {d: load_reset(d) for d in dirs}
    missing = [d for d, r in resets.items() if r is None]
    if missing:
        print(f"no reset.* in {', '.join(missing)}", file=sys.stderr)
        return 2
    session = build_session(task, execute={"controller": "learned"})
    cut = next((s for s in session.skills if s.name == "cut"), None)
    if cut is None:
        print(f"task {task} plans without the cut", file=sys.stderr)
        return 2
    cut.attach_policy(_Recorder())
    dx = cut.config.grid_dx
    rows = []
    for seed in fixed_val_seeds(n):
        try:
            session.episode(seed)
            print(f"{seed}: the plan has no cut", flush=True)
            continue
        except _Recorded as first:
            piece, goal = first.piece, first.goal
        heur = plan_from_goal(piece, goal, cut.config)
        row = {"seed": seed, "heuristic_x": heur.cut_x, "heuristic_plane": heur.plane, "resets": {}}
        inst = session.task.instance(seed)
        first = inst.steps[0] if inst.steps else None
        true_goal, expert_plane = None, None
        if first is not None and first.skill == "cut" and len(piece) == len(inst.init_points):
            true_goal, expert_plane = inst.step_goal(0), cut.reset_target(first.params["cut_x"])[0]
            row["expert_plane"] = expert_plane
        for d, reset in resets.items():
            x = reset.tool_x(cut, piece, goal)
            row["resets"][d] = {"x": x, "phase": x / dx % 1.0, "plane_error_m": cut.reset_target(x)[0] - heur.plane}
            if true_goal is not None:
                row["resets"][d]["true_plane_error_m"] = cut.reset_target(reset.tool_x(cut, piece, true_goal))[0] - expert_plane
        rows.append(row)
        cells = " | ".join(f"{v['x']:.4f} ph {v['phase']:.2f} {v['plane_error_m'] * 1e3:+6.1f} mm"
                           + (f" (true goal {v['true_plane_error_m'] * 1e3:+.1f})" if "true_plane_error_m" in v else "")
                           for v in row["resets"].values())
        print(f"{seed}: heuristic {heur.cut_x:.4f} ph {heur.cut_x / dx % 1.0:.2f} | {cells}", flush=True)
    print("\n| reset regressor | cuts | mean abs plane error (mm) | over 1 cm | on the true post-cut states: mean, over 1 cm |"
          "\n|---|---:|---:|---:|---:|")
    for d in dirs:
        err = np.abs([r["resets"][d]["plane_error_m"] for r in rows]) * 1e3
        true = np.abs([r["resets"][d]["true_plane_error_m"] for r in rows if "true_plane_error_m" in r["resets"][d]]) * 1e3
        cell = f"{true.mean():.1f} mm, {int((true > 10).sum())} of {len(true)}" if len(true) else "-"
        print(f"| {d} | {len(err)} | {err.mean():.1f} | {int((err > 10).sum())} | {cell} |")
    if "out" in args:
        Path(args["out"]).write_text(json.dumps({"task": task, "split": "val", "rows": rows}, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
