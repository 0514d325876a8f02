"""Top and side views of a scene in pictures (``pasta run summary=``, ``pasta replay export=``): the world box
the views show, fitted to the dough, and the tools drawn as outlines in their colour.

A tool primitive (:class:`pasta.io.ToolPrimitive`: a cube, cylinder or sphere of a size, at a pose, in a
colour) is drawn as its outline in a view: the convex hull of its surface projected onto the view's two
world axes (exact for a box, a cylinder and a sphere: each is convex). Numpy only until something is drawn.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

__all__ = ["base_name", "draw_tools", "outline", "surface_samples", "view_box", "within"]

_RING = 32  # points per circle of a cylinder or sphere
#: top view height / width kept within these bounds (a narrower dough leaves room on both sides)
TOP_RATIO = (0.3, 1.6)
#: side view height / width at least this: room above the dough for the tools
SIDE_RATIO = 0.2


def view_box(clouds: Sequence[np.ndarray], up: int = 1, side_ratio: float = SIDE_RATIO) -> tuple[np.ndarray, np.ndarray]:
    """``(lo, hi)`` (3,) world box of a top and a side view of ``clouds`` (each ``(N, 3)``, ``up`` the world
    up axis): every point with a margin of 6% of the larger horizontal span; the top view's height / width
    (second / first horizontal axis) padded into :data:`TOP_RATIO`, the side view's raised to at least
    ``side_ratio`` (tools above the dough stay in view)."""
    pts = np.concatenate([np.asarray(c, np.float64).reshape(-1, 3) for c in clouds])
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    if not len(pts):
        return np.zeros(3), np.ones(3)
    h0, h1 = (a for a in range(3) if a != up)
    lo, hi = pts.min(0), pts.max(0)
    pad = max(0.06 * float(max(hi[h0] - lo[h0], hi[h1] - lo[h1])), 0.01)
    lo, hi = lo - pad, hi + pad
    for wide, narrow, ratio in ((h0, h1, TOP_RATIO[0]), (h1, h0, 1.0 / TOP_RATIO[1])):
        need = ratio * (hi[wide] - lo[wide]) - (hi[narrow] - lo[narrow])
        if need > 0:  # widen the narrow axis about its centre
            lo[narrow] -= need / 2
            hi[narrow] += need / 2
    hi[up] = max(hi[up], lo[up] + side_ratio * (hi[h0] - lo[h0]))
    return lo, hi


def _rotation(quat_wxyz: Sequence[float]) -> np.ndarray:
    w, x, y, z = (float(v) for v in quat_wxyz)
    n = math.sqrt(w * w + x * x + y * y + z * z) or 1.0
    w, x, y, z = w / n, x / n, y / n, z / n
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def surface_samples(tool: Any) -> np.ndarray:
    """``(M, 3)`` world points whose convex hull is the primitive ``tool`` (``kind``, ``size`` full extents,
    ``position``, ``quat_wxyz``): a cube's 8 corners, a cylinder's two end circles (axis: local z), points
    on a sphere (an ellipsoid when the sizes differ)."""
    half = np.asarray(tool.size, np.float64) / 2
    kind = tool.kind
    if kind == "cube":
        local = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], np.float64) * half
    elif kind == "cylinder":
        a = np.linspace(0.0, 2 * math.pi, _RING, endpoint=False)
        ring = np.stack([np.cos(a) * half[0], np.sin(a) * half[1], np.zeros_like(a)], 1)
        local = np.concatenate([ring + np.array([0.0, 0.0, -half[2]]), ring + np.array([0.0, 0.0, half[2]])])
    elif kind == "sphere":
        lat = np.linspace(-math.pi / 2, math.pi / 2, _RING // 2 + 1)
        lon = np.linspace(0.0, 2 * math.pi, _RING, endpoint=False)
        la, lo = np.meshgrid(lat, lon, indexing="ij")
        local = np.stack([np.cos(la) * np.cos(lo), np.sin(la), np.cos(la) * np.sin(lo)], -1).reshape(-1, 3) * half
    else:
        raise ValueError(f"tool primitive kind must be cube, cylinder or sphere, got {kind!r}")
    return local @ _rotation(tool.quat_wxyz).T + np.asarray(tool.position, np.float64)


def _turn(o: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    """> 0 when o -> a -> b turns counter-clockwise."""
    return float((a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]))


def _hull(points: np.ndarray) -> np.ndarray:
    """Convex hull of ``(N, 2)`` points, counter-clockwise (Andrew's monotone chain; deterministic)."""
    pts = np.unique(np.round(points, 12), axis=0)  # sorted by x, then y
    if len(pts) < 3:
        return pts

    def half(seq: np.ndarray) -> list[np.ndarray]:
        out: list[np.ndarray] = []
        for p in seq:
            while len(out) >= 2 and _turn(out[-2], out[-1], p) <= 0:
                out.pop()
            out.append(p)
        return out

    lower, upper = half(pts), half(pts[::-1])
    return np.array(lower[:-1] + upper[:-1])


def outline(tool: Any, plane: tuple[int, int]) -> np.ndarray:
    """``(K, 2)`` polygon of ``tool`` seen in the view whose horizontal and vertical axes are the world axes
    ``plane`` (e.g. ``(0, 2)``: the top view x-z; ``(0, 1)``: the side view x-y)."""
    return _hull(surface_samples(tool)[:, list(plane)])


def within(tool: Any, lo: Sequence[float] | np.ndarray, hi: Sequence[float] | np.ndarray) -> bool:
    """Whether the primitive's bounding box meets the world box ``lo``..``hi`` (3,) (a parked tool does not)."""
    pts = surface_samples(tool)
    return bool(np.all(pts.max(0) >= np.asarray(lo)) and np.all(pts.min(0) <= np.asarray(hi)))


def base_name(name: str) -> str:
    """The tool a primitive belongs to: ``"gripper.1"`` -> ``"gripper"`` (the logs' naming)."""
    head, dot, tail = name.rpartition(".")
    return head if dot and tail.isdigit() else name


def draw_tools(ax: Any, tools: Iterable[Any], plane: tuple[int, int], *, box: tuple[Any, Any] | None = None,
               alpha: float = 0.3, zorder: float = 3.0, fill_zorder: float = 1.0) -> dict[str, tuple[float, ...]]:
    """Draw every primitive of ``tools`` on ``ax`` as its outline in view ``plane``, filled in its colour
    (``alpha``, at ``fill_zorder``: under points drawn at zorder 2) with a solid edge (at ``zorder``).
    ``box``: ``(lo, hi)`` world corners (3,); primitives outside it are left out (parked tools). Returns
    ``{tool name: RGBA}`` of the tools drawn, in drawing order."""
    from matplotlib.patches import Polygon

    drawn: dict[str, tuple[float, ...]] = {}
    for tool in tools:
        if box is not None and not within(tool, *box):
            continue
        poly = outline(tool, plane)
        if len(poly) < 3:
            continue
        rgba = tuple(float(c) for c in tool.color)
        # the fill under the points, the edge over them: the dough stays visible inside a tool's outline
        ax.add_patch(Polygon(poly, closed=True, facecolor=(*rgba[:3], alpha * rgba[3]), edgecolor="none",
                             zorder=fill_zorder))
        ax.add_patch(Polygon(poly, closed=True, fill=False, edgecolor=rgba, linewidth=1.2, zorder=zorder))
        drawn.setdefault(base_name(tool.name), rgba)
    return drawn
