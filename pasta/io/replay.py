"""``pasta replay RUN.mcap``: print a run's timeline, export frames, or re-simulate and verify it.

The CLI registers this module as a subcommand through :func:`add_arguments` and :func:`run`.

Exit codes: 0 success; 1 ``--verify`` found a deviation above ``tolerance=`` (or could not
verify); 2 a bad setting, or the file could not be read (not MCAP, corrupt, truncated without ``--recover``, or a
``sim_config.json`` that is not a valid simulator config).
"""

from __future__ import annotations

import argparse
import functools
import io
import json
import math
import sys
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from pasta.core.errors import ConfigError, PastaError, did_you_mean
from pasta.core.files import save_with
from pasta.io.errors import McapFormatError, McapTruncatedError
from pasta.io.run_log import ACTIONS, DOUGH, FINAL_STATE, INITIAL_STATE, METRICS, PLAN, SIM_CONFIG, STEP, TOOLS
from pasta.io.run_reader import RunReader
from pasta.io.schemas import LOG_SCHEMA, POINT_CLOUD_SCHEMA

EXIT_OK, EXIT_VERIFY_FAILED, EXIT_BAD_FILE = 0, 1, 2
#: the prefix of its error lines, as every ``pasta`` command's
PROG = "pasta replay"

HELP = ("print a run file's timeline, export PNG/GIF frames, recover a truncated file, or re-simulate and --verify it "
        "(RUN.mcap [key=value ...] [--recover] [--verify])")

EPILOG = """settings (key=value; a later item of the same key wins):
  topics=a,b        only these topics in the timeline and the export (comma separated; default every topic)
  export=DIR        write PNG frames (top and side views) and a GIF per cloud topic to DIR
  every=1           export every K-th cloud
  max_frames=300    export at most N frames per topic
  fps=10            GIF frame rate, in (0, 1000]
  up_axis=y         world up axis for the views: x, y or z
  tolerance=1e-5    the largest deviation --verify accepts
  threads=0         the simulator's CPU threads for --verify (Taichi: what computes here); 0: those of the
                    logged run's sim config
examples:
  pasta replay RUN.mcap topics=/plan,/metrics
  pasta replay RUN.mcap export=frames every=2 max_frames=100
  pasta replay RUN.mcap.partial --recover --verify tolerance=1e-4
exit codes: 0 ok; 1 --verify found a deviation above tolerance (or could not verify); 2 a bad setting, or a file
that could not be read (not MCAP, corrupt, truncated without --recover, a bad sim_config.json)"""


@dataclass
class ReplayArgs:
    """The settings of ``pasta replay`` (``key=value``; :data:`EPILOG` says what each does)."""

    topics: str = ""  # comma separated; empty: every topic
    export: str = ""  # a directory; empty: no export
    every: int = 1
    max_frames: int = 300
    fps: float = 10.0
    up_axis: str = "y"
    tolerance: float = 1e-5
    # the simulator is what computes here (--verify); the timeline and the export do not use threads
    threads: int = 0

    def __post_init__(self) -> None:
        from pasta.config.validate import check_choice, check_int, check_number, check_output_dir, check_threads

        check_int(self.every, "every", low=1)
        check_int(self.max_frames, "max_frames", low=1)
        check_number(self.fps, "fps", low=0.0, low_open=True, high=1000.0)
        check_choice(self.up_axis, "up_axis", ("x", "y", "z"))
        check_number(self.tolerance, "tolerance", low=0.0)
        check_threads(self.threads, "threads")
        if self.export:
            check_output_dir(self.export, "export")
        if self.topics.strip() and not self.topic_list():
            raise ConfigError(f"topics={self.topics}: names no topic (give a,b or leave it out for every topic)")

    def topic_list(self) -> list[str] | None:
        """The topics named, or ``None`` for every topic."""
        return [t.strip() for t in self.topics.split(",") if t.strip()] or None


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``replay`` arguments to ``parser``: the run file, settings as ``key=value``, modes as flags."""
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = EPILOG
    parser.add_argument("run_file", metavar="RUN.mcap", help="run file written by pasta.io.RunLogger")
    parser.add_argument("overrides", nargs="*", metavar="key=value", help="settings (below)")
    parser.add_argument("--recover", action="store_true", help="read a truncated file: every complete chunk before the cut")
    parser.add_argument(
        "--verify",
        action="store_true",
        help=f"restore {INITIAL_STATE}, re-apply {ACTIONS} in the simulator and compare the final dough",
    )


def settings(items: list[str]) -> ReplayArgs:
    """The ``key=value`` settings of ``pasta replay``, each checked (a one-line :class:`ConfigError`) before
    any file is read."""
    from pasta.config.overrides import build, split_overrides

    return build(ReplayArgs, split_overrides(items), command=PROG)


def run(args: argparse.Namespace, out: TextIO | None = None) -> int:
    """Execute ``pasta replay`` with parsed ``args``; returns the exit code."""
    out = out or sys.stdout
    err = sys.stderr
    opts = settings(list(args.overrides or ()))  # every setting, before the run file is opened
    topics = opts.topic_list()
    try:
        reader = RunReader(args.run_file, recover=args.recover)
    except McapTruncatedError as e:
        print(f"{PROG}: error: {e}", file=err)
        return EXIT_BAD_FILE
    except McapFormatError as e:
        print(f"{PROG}: error: {e}", file=err)
        return EXIT_BAD_FILE
    with reader:
        try:
            if reader.recover and reader.recover_error:  # a cut, or damage past a whole data section
                n = sum(i.count for i in reader.topic_info().values())
                print(f"warning: recovered {n} messages from a damaged file; {reader.recover_error}", file=err)
            elif reader.status == "failed":
                print(f"warning: the logged run failed: {reader.error}", file=err)
            print_timeline(reader, topics, out)
            if opts.export:
                written = export_frames(
                    reader, Path(opts.export), topics, every=opts.every, max_frames=opts.max_frames,
                    fps=opts.fps, up_axis=opts.up_axis,
                )
                for p in written:
                    print(f"wrote {p}", file=out)
            if args.verify:
                try:
                    ok, _dev = verify_run(reader, opts.tolerance, out, threads=opts.threads)
                except McapFormatError:
                    raise
                except ConfigError as e:  # the file's own sim_config.json is bad: a bad-file error, exit 2
                    print(f"{PROG}: error: {e}", file=err)
                    return EXIT_BAD_FILE
                except PastaError as e:  # the simulator refused the logged state / config / action
                    print(f"{PROG}: error: verify: {e}", file=err)
                    return EXIT_VERIFY_FAILED
                return EXIT_OK if ok else EXIT_VERIFY_FAILED
        except McapFormatError as e:
            print(f"{PROG}: error: {e}", file=err)
            return EXIT_BAD_FILE
    return EXIT_OK


# ---------------------------------------------------------------------------------------------
# timeline


def _secs(t_ns: int) -> str:
    return f"{t_ns / 1e9:.3f}s"


def _compact(obj: Any, limit: int = 160) -> str:
    text = json.dumps(obj, separators=(", ", ": "))
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _fmt_value(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    return json.dumps(v) if not isinstance(v, str) else v


def _fmt_plan(plan: dict[str, Any]) -> str:
    parts = []
    if isinstance(plan.get("skills"), list):
        parts.append(" -> ".join(str(s) for s in plan["skills"]))
    for key in ("score", "cost"):
        if isinstance(plan.get(key), (int, float)):
            parts.append(f"{key}={_fmt_value(plan[key])}")
    rest = {k: v for k, v in plan.items() if k not in ("skills", "score", "cost")}
    if rest:
        parts.append(_compact(rest, 120))
    return "  ".join(parts) if parts else _compact(plan)


def print_timeline(reader: RunReader, topics: list[str] | None, out: TextIO, max_log_lines: int = 50) -> None:
    """Print the topics with counts, run metadata, the plan, per-step results, final metrics and
    log lines (restricted to ``topics`` when given)."""
    info = reader.topic_info()
    shown = [t for t in info if topics is None or t in topics]
    status = {"complete": "complete", "failed": f"FAILED: {reader.error}",
              "truncated": "RECOVERED (truncated: the writer did not finish, e.g. the run was killed)",
              "unknown": "finished, no status record"}[reader.status]
    print(f"run: {reader.path} ({status})", file=out)
    tr = reader.time_range()
    total = sum(i.count for i in info.values())
    span = f"{_secs(tr[0])} .. {_secs(tr[1])}" if tr else "-"
    print(f"writer: {reader.library or '?'}   messages: {total}   time: {span}", file=out)
    meta = reader.metadata()
    if meta:
        print("metadata: " + ", ".join(f"{k}={v}" for k, v in sorted(meta.items())), file=out)
    names = reader.attachment_names()
    if names:
        print("attachments: " + ", ".join(names), file=out)
    if topics is not None:
        missing = [t for t in topics if t not in info]
        if missing:
            print("not in file: " + ", ".join(missing), file=out)
    print("topics:", file=out)
    width = max((len(t) for t in shown), default=5)
    for topic in shown:
        i = info[topic]
        print(f"  {topic:<{width}}  {i.schema_name:<24} {i.count:>7}", file=out)

    if PLAN in shown:
        print("plan:", file=out)
        for t, plan in reader.messages(PLAN):
            print(f"  [{_secs(t)}] {_fmt_plan(plan) if isinstance(plan, dict) else plan}", file=out)
    if STEP in shown:
        print("steps:", file=out)
        for t, step in reader.messages(STEP):
            if isinstance(step, dict):
                head = f"step {step.get('step', '?')}"
                if "skill" in step:
                    head += f" {step['skill']}"
                rest = {k: v for k, v in step.items() if k not in ("step", "skill")}
                body = "  ".join(f"{k}={_fmt_value(v)}" for k, v in rest.items())
                print(f"  [{_secs(t)}] {head}  {body}".rstrip(), file=out)
    if METRICS in shown:
        last = reader.last(METRICS)
        if last is not None:
            t, metrics = last
            body = "  ".join(f"{k}={_fmt_value(v)}" for k, v in metrics.items()) if isinstance(metrics, dict) else str(metrics)
            print(f"final metrics [{_secs(t)}]: {body}", file=out)
    log_topics = [t for t in shown if info[t].schema_name == LOG_SCHEMA]
    if log_topics:
        print("log:", file=out)
        n = 0
        for rec in reader.iter_messages(log_topics, time_order=True):
            n += 1
            if n <= max_log_lines:
                e = rec.value
                print(f"  [{_secs(rec.t_ns)}] {e.level.upper():<7} {e.text}", file=out)
        if n > max_log_lines:
            print(f"  ... {n - max_log_lines} more log lines", file=out)


# ---------------------------------------------------------------------------------------------
# export


def _slug(topic: str) -> str:
    s = "".join(c if c.isalnum() or c in "-_" else "_" for c in topic.strip("/"))
    return s or "root"


def _tool_track(reader: RunReader) -> list[tuple[int, list[Any]]]:
    if TOOLS not in reader.topics():
        return []
    return list(reader.messages(TOOLS))


def _tools_at(track: list[tuple[int, list[Any]]], t_ns: int) -> list[Any]:
    best: list[Any] = []
    for t, tools in track:
        if t <= t_ns:
            best = tools
        else:
            break
    return best


def export_frames(
    reader: RunReader,
    out_dir: Path,
    topics: list[str] | None = None,
    *,
    every: int = 1,
    max_frames: int = 300,
    fps: float = 10.0,
    up_axis: str = "y",
) -> list[Path]:
    """Render each point-cloud topic (default ``/dough``; with ``topics``, every cloud topic among
    them) as PNG frames ``<topic>_<i>.png`` plus ``<topic>.gif``. A frame shows the top view above the
    side view, both at equal scale and with the same limits in every frame (fitted to the exported clouds,
    :func:`pasta.io.views.view_box`), and the tools of the latest ``/tools`` message drawn as their shapes'
    outlines in their logged colours (those outside the views, e.g. parked, are left out; a legend names
    them). Returns the written paths."""
    from PIL import Image

    from pasta.io.views import base_name, view_box, within

    info = reader.topic_info()
    clouds = [t for t, i in info.items() if i.schema_name == POINT_CLOUD_SCHEMA]
    if topics is not None:
        chosen = [t for t in clouds if t in topics]
    else:
        chosen = [DOUGH] if DOUGH in clouds else clouds
    out_dir.mkdir(parents=True, exist_ok=True)
    up = "xyz".index(up_axis)
    track = _tool_track(reader)
    written: list[Path] = []
    for topic in chosen:
        frames: list[tuple[int, np.ndarray, np.ndarray | None]] = []
        for i, (t, pts, colors) in enumerate(reader.point_clouds(topic)):
            if i % max(every, 1) == 0 and len(frames) < max_frames:
                frames.append((t, pts, colors))
        if not frames:
            continue
        box = view_box([f[1] for f in frames], up=up, side_ratio=0.35)  # room for a tool coming down
        legend: dict[str, tuple[float, ...]] = {}  # every tool the frames show in the box: one legend for all
        for t_tools, prims in track:
            if t_tools > frames[-1][0]:
                break
            for p in prims:
                if base_name(p.name) not in legend and within(p, box[0], box[1]):
                    legend[base_name(p.name)] = tuple(p.color)
        pngs = []
        for k, (t, pts, colors) in enumerate(frames):
            fig = _frame_figure(topic, t, pts, colors, _tools_at(track, t), box, up, legend)
            png = out_dir / f"{_slug(topic)}_{k:05d}.png"
            save_with(png, functools.partial(fig.savefig, format="png"))
            pngs.append(png)
        images = [Image.open(p).convert("RGB") for p in pngs]
        gif = out_dir / f"{_slug(topic)}.gif"
        duration = max(int(round(1000.0 / max(fps, 0.1))), 20)
        save_with(gif, functools.partial(images[0].save, format="gif", save_all=True, append_images=images[1:],
                                         duration=duration, loop=0))
        written += [*pngs, gif]
    return written


_FRAME_W = 6.4  # inches


def _frame_figure(topic: str, t: int, pts: np.ndarray, colors: np.ndarray | None, tools: list[Any],
                  box: tuple[np.ndarray, np.ndarray], up: int, legend: dict[str, tuple[float, ...]]) -> Any:
    """One exported frame: the top view above the side view of ``pts`` within ``box``, ``tools`` drawn in
    their colours, a legend of ``legend`` (tool name -> RGBA)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.patches import Patch

    from pasta.io.views import draw_tools

    lo, hi = box
    h0, h1 = (a for a in range(3) if a != up)
    span = hi - lo
    top_h, side_h = _FRAME_W * span[h1] / span[h0], _FRAME_W * span[up] / span[h0]
    fig = Figure(figsize=(_FRAME_W, top_h + side_h + 1.3), dpi=80, layout="constrained")
    FigureCanvasAgg(fig)
    ax_top, ax_side = fig.subplots(2, 1, gridspec_kw={"height_ratios": [top_h, side_h]})
    if colors is not None:
        kw: dict[str, Any] = {"c": colors.astype(np.float32) / 255.0}
    else:
        kw = {"c": pts[:, up], "cmap": "viridis", "vmin": lo[up], "vmax": hi[up]}
    names = "xyz"
    for ax, b, label in ((ax_top, h1, "top view"), (ax_side, up, "side view")):
        ax.scatter(pts[:, h0], pts[:, b], s=5, linewidths=0, zorder=2, **kw)
        draw_tools(ax, tools, (h0, b), box=box)
        ax.set_xlim(lo[h0], hi[h0])
        ax.set_ylim(lo[b], hi[b])
        ax.set_aspect("equal", adjustable="box")
        ax.set_xlabel(names[h0], fontsize=8)
        ax.set_ylabel(names[b], fontsize=8)
        ax.set_title(f"{label} ({names[h0]}-{names[b]})", fontsize=9)
        ax.tick_params(labelsize=7)
    fig.suptitle(f"{topic}  t={_secs(t)}", fontsize=10)
    if legend:
        handles = [Patch(facecolor=(c[0], c[1], c[2], 0.3), edgecolor=(c[0], c[1], c[2], c[3]), linewidth=1.2)
                   for c in legend.values()]
        fig.legend(handles, list(legend), loc="outside lower center", ncols=min(len(legend), 6), fontsize=8,
                   frameon=False)
    return fig


# ---------------------------------------------------------------------------------------------
# verify


def verify_run(reader: RunReader, tolerance: float, out: TextIO | None = None, *,
               threads: int = 0) -> tuple[bool, float]:
    """Restore ``initial_state.npz`` with the logged ``sim_config.json``, re-apply ``/actions`` in
    order and compare the final particle positions with ``final_state.npz`` (or the last ``/dough``
    cloud). Prints the maximum absolute deviation; returns ``(deviation <= tolerance, deviation)``.
    ``threads`` (> 0): the simulator's CPU threads instead of the logged ones (Taichi's, when this process
    starts it)."""
    out = out or sys.stdout
    say: Callable[[str], None] = lambda s: print(s, file=out)  # noqa: E731 - a one-line printer to out
    names = reader.attachment_names()
    for need in (INITIAL_STATE, SIM_CONFIG):
        if need not in names:
            say(f"verify: cannot verify, the run has no attachment {need!r} (has {names})")
            return False, math.inf
    if ACTIONS not in reader.topics():
        say(f"verify: cannot verify, the run has no {ACTIONS} topic")
        return False, math.inf

    from pasta.plugins import get_plugins
    from pasta.sim import Simulator, SimState  # lazy: only verify needs the simulator

    cfg = logged_sim_config(reader)
    if threads > 0:
        cfg = replace(cfg, cpu_threads=int(threads))
    state = SimState.load(io.BytesIO(reader.attachment(INITIAL_STATE)))
    sim = Simulator(cfg, tools=get_plugins().simulated_tools())
    sim.set_state(state)
    n_steps = 0
    for _t, msg in reader.messages(ACTIONS):
        if "set_tool_pose" in msg:
            pose = dict(msg["set_tool_pose"])
            name = pose.pop("name")
            position = np.asarray(pose.pop("position"), dtype=np.float64)
            sim.set_tool_pose(name, position, **pose)
        elif "park_tool" in msg:
            sim.park_tool(msg["park_tool"])
        elif "disturb" in msg:  # the logged disturbance, applied to the re-simulated state
            from pasta.sim.disturb import Disturbance

            Disturbance.from_npz(reader.attachment(str(msg["disturb"]))).apply_to(sim)
        elif "actions" in msg:
            sim.step({k: np.asarray(v, dtype=np.float64) for k, v in msg["actions"].items()})
            n_steps += 1
        elif "tool" in msg and "action" in msg:
            sim.step({msg["tool"]: np.asarray(msg["action"], dtype=np.float64)})
            n_steps += 1
    final = np.asarray(sim.get_state().x, dtype=np.float64)

    if FINAL_STATE in names:
        ref = np.asarray(SimState.load(io.BytesIO(reader.attachment(FINAL_STATE))).x, dtype=np.float64)
        source = FINAL_STATE
        got = final
    else:
        last = reader.last(DOUGH) if DOUGH in reader.topics() else None
        if last is None:
            say(f"verify: cannot verify, the run has neither {FINAL_STATE!r} nor a {DOUGH} cloud")
            return False, math.inf
        ref = np.asarray(last[1], dtype=np.float64)
        source = f"last {DOUGH} message"
        got = final
        if got.shape != ref.shape:
            got = np.asarray(_observed_points(sim.observe()), dtype=np.float64)
    if got.shape != ref.shape:
        say(f"verify: shape mismatch: simulated {got.shape} vs logged {ref.shape} ({source})")
        return False, math.inf
    dev = float(np.max(np.abs(got - ref))) if got.size else 0.0
    ok = dev <= tolerance
    verdict = "OK" if ok else "FAILED"
    say(f"verify: {n_steps} env steps re-simulated; max deviation {dev:.3e} vs {source} (tolerance {tolerance:g}): {verdict}")
    return ok, dev


def logged_sim_config(reader: RunReader) -> Any:
    """The run's ``sim_config.json`` as a :class:`pasta.sim.SimConfig`. A file that is not a JSON object, an unknown key or a bad value raises a one-line
    :class:`~pasta.core.errors.ConfigError` naming the attachment, the key and the known keys."""
    from dataclasses import fields

    from pasta.sim import SimConfig

    where = f"{SIM_CONFIG} in {reader.path}"
    try:
        data = json.loads(reader.attachment(SIM_CONFIG))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ConfigError(f"{where} is not valid JSON: {exc}") from None
    if not isinstance(data, dict):
        raise ConfigError(f"{where} must hold a JSON object of simulator settings, got {type(data).__name__}")
    known = sorted(f.name for f in fields(SimConfig))
    for key in data:
        if key not in known and not str(key).endswith("_friction"):  # an older format: from_dict names it
            raise ConfigError(f"{where}: unknown key '{key}'{did_you_mean(str(key), known)}; "
                              f"known keys: {', '.join(known)}")
    try:
        return SimConfig.from_dict(data)
    except ConfigError as exc:
        raise ConfigError(f"{where}: {exc}") from None
    except TypeError as exc:  # e.g. a nested value of the wrong kind
        raise ConfigError(f"{where}: {exc}") from None


def _observed_points(obs: Any) -> Any:
    """The dough points of ``Simulator.observe()`` whatever its container (array, dict, object)."""
    if isinstance(obs, dict):
        for key in ("dough", "points", "x"):
            if key in obs:
                return obs[key]
    for attr in ("dough", "points", "x"):
        if hasattr(obs, attr):
            return getattr(obs, attr)
    return obs
