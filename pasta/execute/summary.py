"""PNG summary of one executed task episode.

One column per stage, left to right: the initial dough, one column per plan step, and "final vs goal". The
upper row is the top view (x right, z up), the lower row the side view (x right, y up); every panel has the
same limits, fitted to the dough (every cloud drawn, with a margin) at equal scale on both axes, so the side
view shows the dough's real height. A plan step's panel shows the step's planned (decoded) sub-goal in light
pink under the dough observed after the step was executed, in dark blue, with the tool that did it drawn
where its motion ended (its outline in its ``ToolSpec.color``) and its centre's path; the title names the
skill, the planned feasibility and the normalised improvement after the step (its change over the step in
brackets). The last panel shows the goal in grey under the final dough. A legend under the panels names the
colours and the tools drawn. Rendering uses the Agg canvas directly (no pyplot state): headless, thread safe
and deterministic.
"""

from __future__ import annotations

import pathlib
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from pasta.core.errors import InputError
from pasta.core.files import save_with
from pasta.core.shapes import check_points

__all__ = ["ExecutedStep", "build_summary", "save_summary", "summary_steps", "view_limits"]

_PANEL_W = 3.2  # inches per column
_DOUGH_COLOUR = "#1d3557"  # observed dough: initial, after each step, final
_PLANNED_COLOUR = "#f28cc0"  # a step's planned sub-goal (pink: no shipped tool's colour)
_GOAL_COLOUR = "0.72"
_MARKER = 2.0  # scatter marker area (points^2) of observed dough
_UNDER_MARKER = 5.0  # planned sub-goal and goal, drawn under it: larger, so a mismatch shows as a rim

Cloud = np.ndarray


@dataclass(frozen=True)
class ExecutedStep:
    """What executing one plan step did, for its panel.

    Attributes:
        dough: ``(P, 3)`` dough observed after the step.
        improvement: normalised improvement of the episode after the step (``None``: not shown).
        gain: its change over the step (``None``: not shown).
        note: a few words after the improvement, e.g. ``"skipped: at its goal"`` (``""``: none).
        tools: tools drawn in the panel, :class:`pasta.io.ToolPrimitive` s (any objects with ``name``,
            ``kind``, ``size``, ``position``, ``quat_wxyz`` and ``color`` RGBA), where they were when the
            step ended; those outside the panels' box (parked ones) are left out.
        path: ``(T, 3)`` the driven tool's centre over the step, drawn as a dashed line from a circle
            (``None``: no path).
        path_color: the path's colour (a matplotlib colour).
    """

    dough: Any
    improvement: float | None = None
    gain: float | None = None
    note: str = ""
    tools: Sequence[Any] = ()
    path: Any = None
    path_color: Any = "0.3"


def save_summary(
    path: str | pathlib.Path,
    *,
    initial: Any,
    goal: Any,
    final: Any,
    subgoals: Sequence[tuple[str, Sequence[Any]]],
    title: str = "",
    dpi: int = 100,
    executed: Sequence[ExecutedStep | None] | None = None,
    start_tools: Sequence[Any] = (),
    end_tools: Sequence[Any] = (),
) -> pathlib.Path:
    """Write a PNG summary of one episode to ``path`` and return it as a :class:`pathlib.Path`.

    Args:
        path: output file; parent directories are created.
        initial: initial dough ``(P, 3)`` (x, z the table plane, y up).
        goal: goal dough ``(G, 3)``.
        final: final dough ``(P, 3)``.
        subgoals: one ``(label, clouds)`` per plan step, ``clouds`` a list of decoded sub-goal
            pieces ``(Ni, 3)``, e.g. ``("1. cut (f=1.00)", [piece_a, piece_b])``.
        title: figure suptitle.
        dpi: resolution; the image is ``(len(subgoals) + 2) * 3.2 * dpi`` pixels wide.
        executed: one :class:`ExecutedStep` (or ``None``: not executed) per entry of ``subgoals``;
            ``None``: the panels show the plan only.
        start_tools, end_tools: tools (as in :attr:`ExecutedStep.tools`) drawn in the initial and the
            final panel.

    Raises:
        InputError: a cloud is not a finite ``(N, 3)`` array, or ``subgoals`` or ``executed`` is malformed.
            The message names the argument.
    """
    fig = build_summary(initial=initial, goal=goal, final=final, subgoals=subgoals, title=title, executed=executed,
                        start_tools=start_tools, end_tools=end_tools)
    return save_with(path, lambda fh: fig.savefig(fh, dpi=dpi, format="png"))


def build_summary(
    *,
    initial: Any,
    goal: Any,
    final: Any,
    subgoals: Sequence[tuple[str, Sequence[Any]]],
    title: str = "",
    executed: Sequence[ExecutedStep | None] | None = None,
    start_tools: Sequence[Any] = (),
    end_tools: Sequence[Any] = (),
) -> Figure:
    """The summary figure of :func:`save_summary` (same arguments), not yet saved: axes ``[0, i]`` are the
    top views, ``[1, i]`` the side views, column 0 the initial dough, the last column final vs goal."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    from pasta.io.views import draw_tools

    init = _cloud(initial, "initial")
    goal_pts = _cloud(goal, "goal")
    fin = _cloud(final, "final")
    steps = _subgoals(subgoals)
    done = _executed(executed, len(steps))

    # each panel: (title, [(cloud, colour, size)] bottom to top, tools, path or None)
    panels: list[tuple[str, list[tuple[Cloud, str, float]], Sequence[Any], tuple[Cloud, Any] | None]] = [
        ("initial", [(init, _DOUGH_COLOUR, _MARKER)], start_tools, None)]
    for (label, clouds), (ex, dough) in zip(steps, done):
        layers = [(c, _PLANNED_COLOUR, _UNDER_MARKER) for c in clouds]
        if ex is None:
            panels.append((f"{label}\nnot executed (planned sub-goal only)", layers, (), None))
            continue
        assert dough is not None  # an executed step has its observed dough (summary_steps)
        layers.append((dough, _DOUGH_COLOUR, _MARKER))
        path = None
        if ex.path is not None:
            pts = _cloud(ex.path, f"executed path of '{label}'")
            path = (pts, ex.path_color)
        panels.append((f"{label}\n{_executed_line(ex)}", layers, ex.tools, path))
    panels.append(("final vs goal", [(goal_pts, _GOAL_COLOUR, _UNDER_MARKER), (fin, _DOUGH_COLOUR, _MARKER)],
                   end_tools, None))

    lo, hi = view_limits([c for _, layers, _, _ in panels for c, _, _ in layers])
    box = (lo, hi)
    span = hi - lo
    top_h, side_h = _PANEL_W * span[2] / span[0], _PANEL_W * span[1] / span[0]

    n = len(panels)
    fig = Figure(figsize=(n * _PANEL_W, top_h + side_h + 1.4 + (0.4 if title else 0.0)), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(2, n, squeeze=False, gridspec_kw={"height_ratios": [top_h, side_h]})
    tools_seen: dict[str, tuple[float, ...]] = {}
    for col, (label, layers, tools, path) in enumerate(panels):
        top, side = axes[0, col], axes[1, col]
        for ax, (a, b) in ((top, (0, 2)), (side, (0, 1))):
            for pts, colour, size in layers:
                ax.scatter(pts[:, a], pts[:, b], s=size, c=colour, linewidths=0, zorder=2)
            for name, rgba in draw_tools(ax, tools, (a, b), box=box).items():
                tools_seen.setdefault(name, rgba)
            if path is not None:
                pts, colour = path
                ax.plot(pts[:, a], pts[:, b], ls="--", lw=0.9, color=colour, zorder=4)
                ax.plot(pts[0, a], pts[0, b], "o", ms=3.5, mfc="none", mec=colour, mew=0.9, zorder=4)
            ax.set_xlim(lo[0], hi[0])
            ax.set_ylim(lo[b], hi[b])
            ax.set_aspect("equal", adjustable="box")
            ax.tick_params(labelsize=7)
        top.set_title(label, fontsize=9)
        side.set_xlabel("x", fontsize=8)
        if col == 0:
            top.set_ylabel("z (top view)", fontsize=8)
            side.set_ylabel("y (side view)", fontsize=8)

    def dot(colour: str, size: float) -> Line2D:
        return Line2D([], [], ls="none", marker="o", ms=size, color=colour)

    handles: list[Any] = [dot(_DOUGH_COLOUR, 4), dot(_PLANNED_COLOUR, 5), dot(_GOAL_COLOUR, 5)]
    labels = ["observed dough (initial, after each step, final)", "planned sub-goal of the step", "goal"]
    for name, rgba in tools_seen.items():
        red, green, blue, alpha = (float(v) for v in rgba[:4])
        handles.append(Patch(facecolor=(red, green, blue, 0.3), edgecolor=(red, green, blue, alpha), linewidth=1.2))
        labels.append(f"{name} (tool)")
    if any(path is not None for *_, path in panels):
        handles.append(Line2D([], [], ls="--", lw=0.9, color="0.3", marker="o", ms=3.5, mfc="none", markevery=[0]))
        labels.append("tool centre's path (from o)")
    fig.legend(handles, labels, loc="outside lower center", ncols=min(len(handles), 4), fontsize=8, frameon=False)
    if title:
        fig.suptitle(title, fontsize=12)
    return fig


def summary_steps(plan: Any, result: Any, encoder: Any, num_points: int = 400
                  ) -> tuple[list[tuple[str, list[Any]]], list[ExecutedStep | None] | None, list[Any], list[Any]]:
    """The arguments of :func:`save_summary` that describe a plan and its execution: ``(subgoals, executed,
    start_tools, end_tools)``.

    Args:
        plan: the executed :class:`pasta.core.Plan` (``None``: no plan, e.g. the oracle; nothing to show).
        result: its :class:`pasta.execute.ExecutionResult` (``None``: the plan only).
        encoder: decodes each step's sub-goal latents into ``num_points`` points per piece.

    A closed loop that re-planned (``result.plans`` holds more than one plan) gets one panel per executed
    step, each with the sub-goal of the plan it belonged to, then the last plan's steps that did not run; the
    first step's panel says when a disturbance followed it.
    """
    if plan is None:
        return [], None, [], []
    plans = list(getattr(result, "plans", []) or []) if result is not None else []
    if len(plans) > 1:  # a closed loop re-planned: one panel per executed step, then the last plan's rest
        return _replanned_steps(plans, result, encoder, num_points)
    subgoals = [(f"{h + 1}. {step.skill}  (plan f={step.feasibility:.2f})", encoder.decode_clouds(step.subgoal, num_points))
                for h, step in enumerate(plan.steps)]
    if result is None:
        return subgoals, None, [], []
    executed: list[ExecutedStep | None] = [None] * len(subgoals)
    snapshots = list(getattr(result, "snapshots", []) or [])
    before = 0.0
    for k, info in enumerate(result.steps):
        j = info.plan_step if info.plan_step >= 0 else info.step
        gain, before = info.normalized_improvement - before, info.normalized_improvement
        if k >= len(snapshots) or not 0 <= j < len(executed):
            continue
        note = _note(info, result)
        if info.step != j:
            note += f", ran {info.step + 1}."
        executed[j] = _executed_step(snapshots[k], info, gain, note)
    return subgoals, executed, list(getattr(result, "start_tools", [])), list(getattr(result, "end_tools", []))


def _note(info: Any, result: Any) -> str:
    """The panel's note for an executed step: env steps and why it ended, runs, and the disturbance after the
    first step."""
    from pasta.core.step import Stop

    ended = Stop(info.ended)
    note = {Stop.AT_GOAL: "skipped: at its goal", Stop.DIVERGED: "diverged"}.get(ended, f"{info.env_steps} steps")
    if ended in (Stop.LIMIT, Stop.CAP, Stop.REGRESSED):
        note += {Stop.LIMIT: " (step limit)", Stop.CAP: " (policy cap)", Stop.REGRESSED: " (regressed)"}[ended]
    if info.attempts > 1:
        note += f", {info.attempts} runs"
    disturbance = getattr(result, "disturbance", None)
    if info.step == 0 and disturbance and disturbance.get("applied", True):
        note += f"\nthen disturbed: {disturbance['kind']}"
    return note


def _executed_step(snap: Any, info: Any, gain: float, note: str) -> ExecutedStep:
    from pasta.io.views import base_name

    colour = next((tuple(t.color) for t in snap.tools if base_name(t.name) == snap.tool), "0.3")
    return ExecutedStep(snap.dough, info.normalized_improvement, gain, note, snap.tools,
                        snap.path if len(snap.path) else None, colour)


def _replanned_steps(plans: list[Any], result: Any, encoder: Any, num_points: int
                     ) -> tuple[list[tuple[str, list[Any]]], list[ExecutedStep | None], list[Any], list[Any]]:
    """Panels of a closed-loop run: each executed step with the sub-goal of the plan it belonged to (its title
    says which re-plan), then the steps of the last plan that did not run."""
    subgoals: list[tuple[str, list[Any]]] = []
    executed: list[ExecutedStep | None] = []
    snapshots = list(getattr(result, "snapshots", []) or [])
    before, ran = 0.0, set()
    for k, info in enumerate(result.steps):
        step = plans[info.plan].steps[info.plan_step]
        tag = f", re-plan {info.plan}" if info.plan else ""
        subgoals.append((f"{k + 1}. {step.skill}  (plan f={step.feasibility:.2f}{tag})",
                         encoder.decode_clouds(step.subgoal, num_points)))
        gain, before = info.normalized_improvement - before, info.normalized_improvement
        executed.append(_executed_step(snapshots[k], info, gain, _note(info, result)) if k < len(snapshots) else None)
        if info.plan == len(plans) - 1:
            ran.add(info.plan_step)
    last = plans[-1]
    for j, step in enumerate(last.steps):
        if j not in ran:
            subgoals.append((f"{len(subgoals) + 1}. {step.skill}  (plan f={step.feasibility:.2f}, re-plan "
                             f"{len(plans) - 1})", encoder.decode_clouds(step.subgoal, num_points)))
            executed.append(None)
    return subgoals, executed, list(getattr(result, "start_tools", [])), list(getattr(result, "end_tools", []))


def view_limits(clouds: Sequence[Cloud]) -> tuple[np.ndarray, np.ndarray]:
    """``(lo, hi)`` (3,) world box of the summary panels (:func:`pasta.io.views.view_box`, y up): every cloud
    with a margin; the top view (x-z) padded to a height / width ratio within [0.3, 1.6], the side view (x-y)
    raised to at least 0.2 of the width (room for the tools above the dough)."""
    from pasta.io.views import view_box

    return view_box(clouds, up=1)


def _executed_line(ex: ExecutedStep) -> str:
    """``executed: improvement 0.812 (+0.415)`` and the note on a line of its own."""
    line = "executed"
    if ex.improvement is not None:
        line += f": improvement {ex.improvement:.3f}"
        if ex.gain is not None:
            line += f" ({ex.gain:+.3f})"
    return f"{line}\n{ex.note}" if ex.note else line


def _cloud(points: Any, name: str) -> Cloud:
    """``points`` as a finite float64 ``(N, 3)`` array, or :class:`InputError` naming ``name``."""
    if hasattr(points, "detach"):  # torch tensor
        points = points.detach().cpu().numpy()
    try:
        arr = np.asarray(points, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be a numeric (N, 3) array: {exc}") from exc
    return check_points(arr, name)


def _subgoals(subgoals: Any) -> list[tuple[str, list[Cloud]]]:
    """Validate ``subgoals``: a sequence of ``(label: str, clouds: sequence of (Ni, 3))``."""
    if isinstance(subgoals, (str, bytes)) or not isinstance(subgoals, Sequence):
        raise InputError(f"subgoals must be a list of (label, clouds) pairs, got {type(subgoals).__name__}")
    steps = []
    for i, entry in enumerate(subgoals):
        if not isinstance(entry, (tuple, list)) or len(entry) != 2:
            raise InputError(f"subgoals[{i}] must be a (label, clouds) pair, got {entry!r:.80}")
        label, clouds = entry
        if not isinstance(label, str):
            raise InputError(f"subgoals[{i}] label must be a str, got {type(label).__name__}")
        if isinstance(clouds, np.ndarray) or not isinstance(clouds, (tuple, list)):
            raise InputError(
                f"subgoals[{i}] clouds must be a list of (N, 3) arrays, got {type(clouds).__name__}"
            )
        if not clouds:
            raise InputError(f"subgoals[{i}] ('{label}') has no clouds; expected at least one piece")
        steps.append((label, [_cloud(c, f"subgoals[{i}] cloud {j}") for j, c in enumerate(clouds)]))
    return steps


def _executed(executed: Any, n: int) -> list[tuple[ExecutedStep | None, Cloud | None]]:
    """Validate ``executed``: ``None`` or one :class:`ExecutedStep` or ``None`` per step."""
    if executed is None:
        return [(None, None)] * n
    if isinstance(executed, (str, bytes)) or not isinstance(executed, Sequence):
        raise InputError(f"executed must be a list of ExecutedStep (or None), got {type(executed).__name__}")
    if len(executed) != n:
        raise InputError(f"executed has {len(executed)} entries; expected one per plan step ({n})")
    out: list[tuple[ExecutedStep | None, Cloud | None]] = []
    for i, ex in enumerate(executed):
        if ex is None:
            out.append((None, None))
        elif not isinstance(ex, ExecutedStep):
            raise InputError(f"executed[{i}] must be an ExecutedStep or None, got {type(ex).__name__}")
        else:
            out.append((ex, _cloud(ex.dough, f"executed[{i}] dough")))
    return out
