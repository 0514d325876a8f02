"""save_summary: PNG output for a toy episode, input validation, and what the figure shows (legend, planned vs
executed steps, equal-scale views fitted to the dough, tools in their colours)."""

from types import SimpleNamespace

import numpy as np
import pytest
from matplotlib.colors import to_rgba
from matplotlib.image import imread
from matplotlib.patches import Polygon

from pasta.core.errors import InputError
from pasta.execute.summary import ExecutedStep, build_summary, save_summary, summary_steps
from pasta.io import ToolPrimitive

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def box(rng, centre, n=200, size=(0.1, 0.05, 0.1)):
    return np.asarray(centre) + (rng.random((n, 3)) - 0.5) * np.asarray(size)


def episode(rng, steps):
    initial = box(rng, (0.5, 0.025, 0.5), size=(0.3, 0.05, 0.2))
    subgoals = [
        (f"{i + 1}. cut", [box(rng, (0.4, 0.025, 0.5)), box(rng, (0.6, 0.025, 0.5))]) for i in range(steps)
    ]
    goal = box(rng, (0.5, 0.03, 0.4))
    final = box(rng, (0.52, 0.03, 0.42))
    return dict(initial=initial, goal=goal, final=final, subgoals=subgoals)


def test_writes_png_sized_by_panels(tmp_path):
    rng = np.random.default_rng(0)
    path = save_summary(tmp_path / "a" / "b" / "three.png", title="toy episode", **episode(rng, 3))
    assert path == tmp_path / "a" / "b" / "three.png"
    assert path.read_bytes()[:8] == PNG_SIGNATURE
    assert path.stat().st_size < 300_000
    h3, w3 = imread(path).shape[:2]
    assert w3 > h3

    h1, w1 = imread(save_summary(tmp_path / "one.png", **episode(rng, 1))).shape[:2]
    assert w3 > w1
    assert abs((w3 - w1) - 2 * (w1 / 3)) <= 2  # 5 vs 3 panels of equal width


def test_accepts_float32_and_no_steps(tmp_path):
    rng = np.random.default_rng(1)
    ep = episode(rng, 0)
    ep = {k: v.astype(np.float32) if isinstance(v, np.ndarray) else v for k, v in ep.items()}
    assert save_summary(str(tmp_path / "zero.png"), **ep).read_bytes()[:8] == PNG_SIGNATURE


@pytest.mark.parametrize("name", ["initial", "goal", "final"])
@pytest.mark.parametrize("bad", ["nan", "shape", "empty"])
def test_bad_cloud_names_argument(tmp_path, name, bad):
    ep = episode(np.random.default_rng(2), 1)
    if bad == "nan":
        ep[name] = ep[name].copy()
        ep[name][3, 1] = np.nan
    elif bad == "shape":
        ep[name] = ep[name][:, :2]
    else:
        ep[name] = np.zeros((0, 3))
    with pytest.raises(InputError, match=name):
        save_summary(tmp_path / "x.png", **ep)
    assert not (tmp_path / "x.png").exists()


@pytest.mark.parametrize(
    "subgoals",
    [
        "1. cut",  # not a list
        [("1. cut",)],  # not a pair
        [(3, [np.zeros((5, 3))])],  # label not a str
        [("1. cut", np.zeros((5, 3)))],  # clouds is one array, not a list
        [("1. cut", [])],  # no pieces
        [("1. cut", [np.zeros((5, 2))])],  # piece of wrong shape
        [("1. cut", [np.full((5, 3), np.inf)])],  # non-finite piece
    ],
)
def test_bad_subgoals_names_argument(tmp_path, subgoals):
    ep = episode(np.random.default_rng(3), 0)
    ep["subgoals"] = subgoals
    with pytest.raises(InputError, match="subgoals"):
        save_summary(tmp_path / "x.png", **ep)


# ------------------------------------------------------------------ what the figure shows

KNIFE_RGBA = to_rgba("tab:red")


def knife(x=0.5, y=0.05, z=0.5):
    return ToolPrimitive("knife", "cube", (0.02, 0.1, 0.12), (x, y, z), color=KNIFE_RGBA)


def executed_episode(rng):
    ep = episode(rng, 2)
    parked = ToolPrimitive("roller", "cylinder", (0.06, 0.06, 0.15), (0.75, 0.8, 0.12), color=to_rgba("tab:purple"))
    ep["executed"] = [
        ExecutedStep(box(rng, (0.5, 0.025, 0.5), size=(0.3, 0.05, 0.2)), 0.397, 0.397, "52 steps",
                     tools=[knife(), parked], path=np.array([[0.5, 0.2, 0.5], [0.5, 0.05, 0.5]]),
                     path_color=KNIFE_RGBA),
        None,  # not executed (e.g. the episode diverged before it)
    ]
    return ep


def tool_patches(ax, rgba):
    """The outlines on ``ax`` drawn in colour ``rgba``."""
    return [p for p in ax.patches if isinstance(p, Polygon) and np.allclose(p.get_edgecolor(), rgba)]


def test_legend_names_every_colour_and_the_tools_drawn(tmp_path):
    fig = build_summary(**executed_episode(np.random.default_rng(4)))
    [legend] = fig.legends
    texts = [t.get_text() for t in legend.get_texts()]
    for needle in ("observed dough", "planned sub-goal", "goal", "knife (tool)", "path"):
        assert any(needle in t for t in texts), (needle, texts)
    assert not any("roller" in t for t in texts)  # parked far above the dough: not drawn, not in the legend


def test_step_panels_show_plan_and_execution_with_the_improvement():
    ep = executed_episode(np.random.default_rng(5))
    fig = build_summary(**ep)
    axes = np.array(fig.axes).reshape(2, -1)
    assert axes.shape[1] == 4  # initial, two steps, final
    first, second = axes[0, 1].get_title(), axes[0, 2].get_title()
    assert first.startswith("1. cut") and "improvement 0.397 (+0.397)" in first and "52 steps" in first
    assert "not executed" in second
    # the executed step draws the planned pieces and the observed dough; the unexecuted one the plan only
    assert len(axes[0, 1].collections) == 3 and len(axes[0, 2].collections) == 2
    # the knife is drawn in its colour in both views of the executed step, nowhere else
    assert tool_patches(axes[0, 1], KNIFE_RGBA) and tool_patches(axes[1, 1], KNIFE_RGBA)
    assert not any(tool_patches(ax, KNIFE_RGBA) for ax in axes[:, [0, 2, 3]].ravel())


def test_panels_fit_the_dough_at_equal_scale():
    rng = np.random.default_rng(6)
    ep = episode(rng, 1)
    fig = build_summary(**ep)
    fig.canvas.draw()
    pts = np.concatenate([ep["initial"], ep["goal"], ep["final"], *ep["subgoals"][0][1]])
    lo, hi = pts.min(0), pts.max(0)
    axes = np.array(fig.axes).reshape(2, -1)
    for col in range(axes.shape[1]):
        for ax, b in ((axes[0, col], 2), (axes[1, col], 1)):
            (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
            assert x0 < lo[0] and x1 > hi[0] and y0 < lo[b] and y1 > hi[b]  # every point inside
            assert x1 - x0 < 1.3 * (hi[0] - lo[0])  # with a margin, not the whole workspace
            if b == 2:
                assert y1 - y0 < 1.3 * (hi[2] - lo[2])
            # equal scale: the drawn box has the limits' aspect (the side view is not stretched)
            bbox = ax.get_window_extent()
            assert ax.get_aspect() == 1.0
            assert bbox.height / bbox.width == pytest.approx((y1 - y0) / (x1 - x0), rel=0.03)


def test_tool_colour_appears_in_the_png_where_the_tool_is(tmp_path):
    ep = executed_episode(np.random.default_rng(7))
    red = np.array(KNIFE_RGBA[:3])

    def red_columns(path):  # the columns of the panels (the legend, at the bottom, left out) with knife red
        img = imread(path)[..., :3]
        img = img[: int(0.85 * img.shape[0])]
        mask = np.abs(img - red).max(-1) < 0.12
        return np.flatnonzero(mask.any(0)), img.shape[1]

    cols, width = red_columns(save_summary(tmp_path / "with.png", **ep))
    assert len(cols) > 0
    assert width / 4 < cols.min() and cols.max() < width / 2  # only in the second of four columns: step 1
    ep["executed"][0] = ExecutedStep(ep["executed"][0].dough, 0.397, 0.397)  # no tools, no path
    assert len(red_columns(save_summary(tmp_path / "without.png", **ep))[0]) == 0


def test_summary_is_deterministic(tmp_path):
    ep = executed_episode(np.random.default_rng(8))
    a = save_summary(tmp_path / "a.png", **ep).read_bytes()
    assert save_summary(tmp_path / "b.png", **ep).read_bytes() == a


@pytest.mark.parametrize("executed", ["x", [None], [None, None, None], [np.zeros((5, 3)), None]])
def test_bad_executed_names_argument(tmp_path, executed):
    ep = episode(np.random.default_rng(9), 2)
    with pytest.raises(InputError, match="executed"):
        save_summary(tmp_path / "x.png", executed=executed, **ep)
    assert not (tmp_path / "x.png").exists()


def test_summary_steps_follow_the_plan_order_and_the_executed_order():
    class Decoder:
        def decode_clouds(self, latent, n):
            return [np.full((n, 3), float(latent))]

    plan = SimpleNamespace(steps=[SimpleNamespace(skill=s, feasibility=0.9, subgoal=i) for i, s in enumerate(["cut", "push", "roll"])])

    def info(step, plan_step, ni, ended="done", attempts=1):
        return SimpleNamespace(step=step, plan_step=plan_step, normalized_improvement=ni, ended=ended,
                               env_steps=10 + step, attempts=attempts)

    def snap(v, tool):
        return SimpleNamespace(dough=np.full((4, 3), v), tools=[knife()], tool=tool, path=np.zeros((2, 3)))

    # plan step 2 ran second (at its goal: skipped), plan step 1 third after two runs
    result = SimpleNamespace(steps=[info(0, 0, 0.4), info(1, 2, 0.5, "at_goal", 0), info(2, 1, 0.8, "limit", 2)],
                             snapshots=[snap(1, "knife"), snap(2, "roller"), snap(3, "pusher")],
                             start_tools=[knife()], end_tools=[])
    subgoals, executed, start, end = summary_steps(plan, result, Decoder(), num_points=5)
    assert [label for label, _ in subgoals] == ["1. cut  (plan f=0.90)", "2. push  (plan f=0.90)", "3. roll  (plan f=0.90)"]
    assert subgoals[2][1][0].shape == (5, 3) and subgoals[2][1][0][0, 0] == 2.0
    cut, push, roll = executed
    assert (cut.improvement, cut.gain, cut.note) == (0.4, 0.4, "10 steps")
    assert cut.path_color == KNIFE_RGBA and cut.dough[0, 0] == 1
    assert roll.improvement == 0.5 and roll.gain == pytest.approx(0.1) and roll.note.startswith("skipped")
    assert push.gain == pytest.approx(0.3) and push.note == "12 steps (step limit), 2 runs, ran 3."
    assert push.path_color == "0.3"  # the pusher is not among the drawn tools: the default grey
    assert len(start) == 1 and end == []
    assert summary_steps(None, None, Decoder()) == ([], None, [], [])
    assert summary_steps(plan, None, Decoder(), num_points=5)[1] is None
