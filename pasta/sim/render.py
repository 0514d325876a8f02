"""Matplotlib (Agg) pictures of a scene: top view (x-z) and side view (x-y)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from pasta.core.files import save_with

#: tools without a ToolSpec.color take these in turn
_PALETTE = ("tab:red", "tab:green", "tab:purple", "tab:blue", "tab:brown", "tab:pink", "tab:olive", "tab:cyan")


def _tool_colors(names, given) -> dict[str, str]:
    """{tool name: colour}: ``given`` where it names one, else the palette in turn."""
    given = dict(given or {})
    out, i = {}, 0
    for n in names:
        if given.get(n):
            out[n] = given[n]
        else:
            out[n] = _PALETTE[i % len(_PALETTE)]
            i += 1
    return out


def render_png(path, dough_points, tool_points=None, goal_points=None, title: str | None = None,
               labels=None, colors=None) -> Path:
    """Write a PNG with a top view (x-z) and a side view (x-y) of the workspace.

    dough_points: (N, 3); tool_points: (T, 3) or {name: (T, 3)}; goal_points: (G, 3) drawn faint;
    labels: optional (N,) ints colouring the dough (e.g. DBSCAN clusters); colors: {tool name: matplotlib
    colour} (e.g. each ToolSpec.color), the others take a palette in turn. Returns the path.
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    d = np.asarray(dough_points, dtype=float).reshape(-1, 3)
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.6))
    tools = tool_points if isinstance(tool_points, dict) else ({"tool": tool_points} if tool_points is not None else {})
    colors = _tool_colors(list(tools), colors)
    views = [(0, 2, "top view (x-z)", "z", (0.2, 0.8)), (0, 1, "side view (x-y)", "y", (0.0, 0.3))]
    for ax, (a, b, name, yl, ylim) in zip(axes, views):
        if goal_points is not None:
            g = np.asarray(goal_points, dtype=float).reshape(-1, 3)
            ax.scatter(g[:, a], g[:, b], s=2, c="0.75", label="goal")
        ax.scatter(d[:, a], d[:, b], s=2, c=labels if labels is not None else "tab:orange",
                   cmap="tab10" if labels is not None else None, label="dough")
        for k, pts in tools.items():
            p = np.asarray(pts, dtype=float).reshape(-1, 3)
            ax.scatter(p[:, a], p[:, b], s=4, c=colors[k], label=k)
        if b == 1:
            ax.axhline(0.02, color="0.5", lw=0.8)
        ax.set_xlim(0.0, 1.0)
        ax.set_ylim(*ylim)
        ax.set_aspect("equal")
        ax.set_xlabel("x")
        ax.set_ylabel(yl)
        ax.set_title(name)
    axes[0].legend(loc="upper left", fontsize=7, markerscale=3)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    path = save_with(path, lambda fh: fig.savefig(fh, dpi=110, format="png"))
    plt.close(fig)
    return path
