"""PNG summary of one executed task episode.

Draws one row of top-down scatter panels (x horizontal, z vertical): the initial dough, one panel per
plan step with that step's decoded sub-goal pieces (one colour per piece, the step label as title),
and a last "final vs goal" panel with the goal in light grey under the final dough. A second, shorter
row shows the same panels from the side (x horizontal, y up). Every panel shares the same limits,
derived from all clouds. Rendering uses the Agg canvas directly (no pyplot state): headless and
thread safe.
"""

from __future__ import annotations

import pathlib
from collections.abc import Sequence
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from pasta.core.errors import InputError
from pasta.core.files import save_with
from pasta.core.shapes import check_points

__all__ = ["save_summary"]

_PANEL_W = 2.6  # inches per panel
_TOP_H = 2.8  # inches of the top-down row
_SIDE_H = 1.2  # inches of the side-view row
_GOAL_COLOUR = "0.8"
_FINAL_COLOUR = "tab:red"
_DOUGH_COLOUR = "tab:blue"
_MARKER = 1.5  # scatter marker area (points^2)

Cloud = np.ndarray
Panel = tuple[str, list[tuple[Cloud, str]]]


def save_summary(
    path: str | pathlib.Path,
    *,
    initial: Any,
    goal: Any,
    final: Any,
    subgoals: Sequence[tuple[str, Sequence[Any]]],
    title: str = "",
    dpi: int = 100,
) -> pathlib.Path:
    """Write a PNG summary of one episode to ``path`` and return it as a :class:`pathlib.Path`.

    Args:
        path: output file; parent directories are created.
        initial: initial dough ``(P, 3)`` (x, z the table plane, y up).
        goal: goal dough ``(G, 3)``.
        final: final dough ``(P, 3)``.
        subgoals: one ``(label, clouds)`` per plan step, ``clouds`` a list of decoded sub-goal
            pieces ``(Ni, 3)``, e.g. ``("1. cut", [piece_a, piece_b])``.
        title: figure suptitle.
        dpi: resolution; the image is ``(len(subgoals) + 2) * 2.6 * dpi`` pixels wide.

    Raises:
        InputError: a cloud is not a finite ``(N, 3)`` array, or ``subgoals`` is malformed. The
            message names the argument.
    """
    init = _cloud(initial, "initial")
    goal_pts = _cloud(goal, "goal")
    fin = _cloud(final, "final")
    steps = _subgoals(subgoals)

    panels: list[Panel] = [("initial", [(init, _DOUGH_COLOUR)])]
    for label, clouds in steps:
        panels.append((label, [(c, f"C{j % 10}") for j, c in enumerate(clouds)]))
    panels.append(("final vs goal", [(goal_pts, _GOAL_COLOUR), (fin, _FINAL_COLOUR)]))

    all_pts = np.concatenate([c for _, layers in panels for c, _ in layers])
    lo, hi = all_pts.min(0), all_pts.max(0)
    x_lim, z_lim = _square_limits(lo[[0, 2]], hi[[0, 2]])
    y_pad = max(0.1 * (hi[1] - lo[1]), 0.01)
    y_lim = (lo[1] - y_pad, hi[1] + y_pad)

    n = len(panels)
    fig = Figure(figsize=(n * _PANEL_W, _TOP_H + _SIDE_H + (0.4 if title else 0.0)), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(2, n, squeeze=False, gridspec_kw={"height_ratios": [_TOP_H, _SIDE_H]})
    for col, (label, layers) in enumerate(panels):
        top, side = axes[0, col], axes[1, col]
        for pts, colour in layers:
            top.scatter(pts[:, 0], pts[:, 2], s=_MARKER, c=colour, linewidths=0)
            side.scatter(pts[:, 0], pts[:, 1], s=_MARKER, c=colour, linewidths=0)
        top.set_title(label, fontsize=10)
        top.set_xlim(*x_lim)
        top.set_ylim(*z_lim)
        top.set_aspect("equal", adjustable="box")
        side.set_xlim(*x_lim)
        side.set_ylim(*y_lim)
        for ax in (top, side):
            ax.tick_params(labelsize=7)
        if col == 0:
            top.set_ylabel("z (top view)", fontsize=8)
            side.set_ylabel("y (side view)", fontsize=8)
        side.set_xlabel("x", fontsize=8)
    if title:
        fig.suptitle(title, fontsize=12)

    return save_with(path, lambda fh: fig.savefig(fh, dpi=dpi, format="png"))


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


def _square_limits(lo: np.ndarray, hi: np.ndarray) -> tuple[tuple[float, float], tuple[float, float]]:
    """Padded limits of two axes with the same span, so equal aspect fills a square panel."""
    centre = (lo + hi) / 2
    half = max(float((hi - lo).max()) / 2 * 1.1, 0.02)
    return (centre[0] - half, centre[0] + half), (centre[1] - half, centre[1] + half)
