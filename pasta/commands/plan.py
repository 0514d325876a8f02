"""``pasta plan obs=FILE goal=FILE [key=value ...]``: plan from two point-cloud files, no simulator.

Each cloud (``.npy`` ``(P, 3)`` or organised ``(H, W, 3)`` with NaN holes, PLY ascii or binary) is put in
the workspace frame (``units=``, ``up=``, ``transform=``), optionally preprocessed (``preprocess=camera``
and ``preprocess.*``: :mod:`pasta.perception`), then perceived, planned and checked by the one path that
``pasta run`` and ``pasta eval`` use (:func:`pasta.execute.episode.perceive_and_plan`: decomposition with
``perception.*``, encoding, the training-box check ``check.box_margin``, planning, the plan's checks and
flags ``check.*``), with the skills the scene allows (``scene=auto|none|TOOL,...``, :mod:`pasta.tasks.scene`).
Writes ``plan.json`` (with ``info.confidence``, ``info.flags`` and ``info.scene``), per step
``h`` the decoded sub-goal entities ``step_{h}_subgoal.npy`` ``(M_h, P, 3)`` (workspace frame) and, for
another input frame, ``step_{h}_subgoal_input.npy`` (the input's frame and units), and the per-point
entity labels ``obs_labels.npy`` / ``goal_labels.npy`` (shaped like the input, ``-1`` for dropped
points) to ``out=DIR``. Exit codes: 0 a plan, 2 bad input or config, 3 a plan written but flagged
unreachable (docs/real_world.md).

Hardened against hostile inputs: ``out=`` and every key are checked before anything is computed; clouds
above ``perception.max_points`` are voxel-downsampled before DBSCAN (whose memory grows with
the square of a dense cloud's size); clouds must lie in the unit-cube workspace and hold at least
``perception.min_points`` points; encoded latents, the plan (:meth:`pasta.core.Plan.check`) and the decoded
sub-goals are checked for NaN and ranges before anything is written, and ``plan.json`` (strict JSON) is
written last, under a temporary name renamed into place.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path
from typing import Any

from pasta.core.errors import ConfigError, InputError
from pasta.core.files import OutputLock

HELP = ("plan from an observed and a goal point cloud (.npy or .ply): obs=FILE goal=FILE [out=DIR] [units=m|mm] "
        "[up=y|z] [transform=FILE] [preprocess=none|camera] [scene=auto|none|TOOL,...] [key=value ...]")

#: keys of this command: the input files, where the plan goes, and the input contract (docs/real_world.md);
#: every other key is a run-config key (perception.*, check.*, horizon, skills, skeleton, planner, ...)
COMMAND_KEYS = {
    "obs": None,
    "goal": None,
    "out": "plan_out",
    "units": "m",
    "up": "y",
    "transform": "",
    # the scene the skills must fit (pasta.tasks.scene): auto (detected from the clouds), none, or static tools
    "scene": "auto",
    # preprocessing (pasta.perception.preprocess): a preset, then single keys over it ("" = the preset's value)
    "preprocess": "none",
    **{f"preprocess.{k}": "" for k in ("crop", "crop_low", "crop_high", "table", "table_height", "table_margin",
                                        "outliers", "outlier_k", "outlier_std", "complete", "fill_spacing")},
}

#: the horizon of ``pasta plan`` when ``horizon=`` is not given (no task to take it from)
DEFAULT_HORIZON = 3

#: exit code of a plan that was written but is flagged unreachable (2 is bad input or config)
EXIT_UNREACHABLE = 3

#: a cloud file with more points is refused before it is read (loading and downsampling cost ~80 bytes
#: a point); downsample such clouds before `pasta plan`
MAX_FILE_POINTS = 10_000_000

#: the workspace every cloud must lie in (the simulator's unit cube, y up)
WORKSPACE = (0.0, 1.0)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("overrides", nargs="*", metavar="key=value",
                        help="obs=FILE goal=FILE out=DIR units=m|mm up=y|z transform=FILE preprocess=none|camera "
                             "preprocess.KEY=V scene=auto|none|TOOL,... (docs/real_world.md), and any run-config "
                             "key (`pasta config`): "
                             "models=DIR horizon=H skills=a,b skeleton=a,b,c threads=1 seed=S planner=NAME "
                             "planner.* perception.num_points/min_points/max_points/eps/min_samples check.*")


def split_arguments(items: list[str]) -> tuple[dict[str, str], list[str]]:
    """Separate this command's keys from run-config overrides."""
    mine: dict[str, str] = {k: v for k, v in COMMAND_KEYS.items() if v is not None}
    rest = []
    for item in items:
        key, eq, value = item.partition("=")
        if eq and key.strip() in COMMAND_KEYS:
            mine[key.strip()] = value.strip()
        else:
            rest.append(item)
    for key in ("obs", "goal"):
        if not mine.get(key):
            raise ConfigError(f"pasta plan needs {key}=FILE (a .npy (P, 3) array or an ASCII .ply point cloud)")
    return mine, rest


def load_cloud(path: str | Path, name: str = "cloud"):
    """Read a ``(P, 3)`` float32 point cloud from ``.npy`` (``(P, 3)`` or organised ``(H, W, 3)``, whose NaN
    holes are dropped) or PLY (ascii or binary); bad files raise InputError."""
    import numpy as np

    from pasta.core.shapes import check_points

    loaded = read_cloud(path, name)
    check_points(loaded.points, f"{name} cloud {Path(path).name}")
    return np.ascontiguousarray(loaded.points, dtype=np.float32)


def read_cloud(path: str | Path, name: str = "cloud"):
    """:func:`pasta.perception.read_cloud` with this module's :data:`MAX_FILE_POINTS`."""
    from pasta.perception import clouds

    return clouds.read_cloud(path, name, max_file_points=MAX_FILE_POINTS)


def run(args: argparse.Namespace) -> int:
    return plan_files(args.overrides)


def plan_files(items: list[str], *, plugins: Any = None) -> int:
    """Run ``pasta plan`` on ``key=value`` items; return the exit code (0, or :data:`EXIT_UNREACHABLE` for a
    plan written but flagged unreachable; errors raise :class:`PastaError`)."""
    import numpy as np

    from pasta.config.validate import check_input_file, check_output_dir

    mine, overrides = split_arguments(list(items))
    camera = camera_options(mine)
    out = check_output_dir(mine["out"], "out")  # before anything is computed: a bad out= must not cost a plan
    for key in ("obs", "goal"):
        check_input_file(mine[key], key)
    OutputLock(out, "out").acquire()  # one writer per out=: a second plan stops here
    if plugins is None:
        from pasta.plugins import get_plugins

        plugins = get_plugins()
    from pasta.commands._progress import planning_bar
    from pasta.commands.run import apply_threads
    from pasta.config import load_config, section, split_names
    from pasta.execute.episode import perceive_and_plan
    from pasta.tasks.scene import AUTO, detect_scene, floor_height, scene_from_setting
    from pasta.execute.skillset import choose_skills, needs_feasibility_network
    from pasta.weights import models_root, weight_overrides

    cfg = load_config(overrides, plugins=plugins)
    check_cpu_only(cfg)
    if cfg.get("task") is not None:
        raise ConfigError("pasta plan plans between two cloud files and takes no task= (use `pasta run task=...`)")
    root = models_root(cfg.models)
    if cfg.models:  # the encoder and cost weights under the given root unless set explicitly
        cfg = load_config(overrides + weight_overrides(root, overrides), plugins=plugins)
    apply_threads(cfg)
    perception, check = section(cfg, "perception"), section(cfg, "check")
    skeleton = tuple(split_names(cfg.skeleton, "skeleton")) or None
    if skeleton == ("task",):
        raise ConfigError("skeleton=task needs a task (pasta run / pasta eval); give the skills: skeleton=cut,push,roll")
    floor = floor_height(int(cfg.sim.n_grid))
    scene = None if mine["scene"].strip() == AUTO else scene_from_setting(mine["scene"], floor, plugins=plugins)
    # a bad skills= or skeleton= is refused before any cloud is read (with scene=auto, fitted again once detected)
    choice = choose_skills(split_names(cfg.skills, "skills") or None, root, plugins=plugins, scene=scene)
    choice.require(skeleton or (), "skeleton=")
    frame = camera["frame"]  # every key is checked: the work starts
    loaded, clouds, kept, kept_points = {}, {}, {}, {}
    for name in ("obs", "goal"):
        loaded[name] = read_cloud(mine[name], name)
        clouds[name], kept[name], kept_points[name] = prepare_input(loaded[name], name, frame, camera["preprocess"],
                                                                     perception)
    if scene is None:  # scene=auto: the surfaces the dough rests on (as `pasta run` takes the task's scene)
        scene = detect_scene((clouds["obs"], clouds["goal"]), floor, perception=perception)
        choice = choose_skills(split_names(cfg.skills, "skills") or None, root, plugins=plugins, scene=scene)
        choice.require(skeleton or (), "skeleton=")
    print(choice.scene_note())

    encoder = plugins.encoders.create(cfg.encoder.name, section(cfg, "encoder"))
    cost = plugins.cost_models.create(cfg.cost_model.name, section(cfg, "cost_model"))
    if choice.warning():
        print(choice.warning(), file=sys.stderr)
    skills = [plugins.skills.create(n, section(cfg, f"skill.{n}") if n in cfg.skill else None) for n in choice.names]
    needs = [s for s in skills if needs_feasibility_network(s)]
    if needs:
        from pasta.nn.loading import attach_feasibility

        attach_feasibility(needs, root, latent_dim=encoder.latent_dim)
    planner = plugins.planners.create(cfg.planner.name, section(cfg, "planner"))
    with planning_bar():  # iterations, candidates and an ETA, as `pasta run` shows them; on a terminal only
        seen = perceive_and_plan(clouds["obs"], clouds["goal"], planner=planner, planner_name=cfg.planner.name,
                                 encoder_name=cfg.encoder.name,
                                 skills=skills, encoder=encoder, cost=cost,
                                 horizon=int(cfg.horizon or len(skeleton or ()) or DEFAULT_HORIZON),
                                 seed=int(cfg.seed), skeleton=skeleton, perception=perception, check=check)
    labels = {name: point_labels(loaded[name], kept[name], kept_points[name], seen.clouds[name], seen.labels[name])
              for name in ("obs", "goal")}
    plan = dataclasses.replace(seen.plan, info={**seen.plan.info, "scene": choice.record(), "input": {
        "frame": frame.describe(), "preprocess": camera["preprocess"].to_dict(),
        "decompose": {"eps": perception.eps, "min_samples": perception.min_samples, "min_points": perception.min_points}}})
    text = plan.to_json()
    subgoals = []
    for h, step in enumerate(plan.steps):
        clouds_h = np.stack(encoder.decode_clouds(step.subgoal, perception.num_points))
        if not np.isfinite(clouds_h).all():
            raise InputError(f"plan step {h + 1} ({step.skill}): the encoder {cfg.encoder.name!r} decodes its "
                             "sub-goal latents to NaN or infinite points")
        subgoals.append(clouds_h.astype(np.float32))
    files = write_outputs(out, text, subgoals, {"obs": len(seen.entities["obs"]), "goal": len(seen.entities["goal"])},
                          labels=labels, frame=frame)
    print(plan.summary())
    for flag in seen.flags:
        print(f"warning: {flag['kind']}: {flag['message']}", file=sys.stderr)
    print(f"wrote {out / 'plan.json'} and {len(files)} sub-goal clouds to {out}")
    return EXIT_UNREACHABLE if seen.unreachable else 0


def camera_options(mine: dict[str, str]) -> dict[str, Any]:
    """The input-contract and preprocessing keys, validated (one-line ConfigError)."""
    from pasta.config.validate import check_choice, check_int, check_number
    from pasta.perception import PRESETS, CloudFrame, read_transform

    units = check_choice(mine["units"], "units", ["m", "mm"])
    up = check_choice(mine["up"], "up", ["y", "z"])
    transform = None
    if mine["transform"]:
        try:
            transform = read_transform(mine["transform"])
        except InputError as exc:
            raise ConfigError(f"transform={mine['transform']}: {exc}") from None
    preset = dict(PRESETS[check_choice(mine["preprocess"], "preprocess", list(PRESETS))])
    kinds = {"crop": "bool", "crop_low": "xyz", "crop_high": "xyz", "table": ("none", "height", "ransac"), "table_height": "float",
             "table_margin": "positive", "outliers": ("none", "statistical"), "outlier_k": "int",
             "outlier_std": "positive", "complete": ("none", "fill"), "fill_spacing": "positive"}
    for key, kind in kinds.items():
        value, full = mine.get(f"preprocess.{key}", ""), f"preprocess.{key}"
        if value == "":
            continue
        if kind == "bool":
            preset[key] = check_choice(value.lower(), full, ["true", "false"]) == "true"
        elif kind == "xyz":
            parts = value.split(",")
            if len(parts) != 3:
                raise ConfigError(f"{full}={value}: must be three comma-separated numbers x,y,z")
            preset[key] = tuple(check_number(v, full, low=-10.0, high=10.0) for v in parts)
        elif kind == "float":
            preset[key] = check_number(value, full, low=-1.0, high=2.0)
        elif kind == "positive":
            preset[key] = check_number(value, full, low=0.0, low_open=True, high=1.0)
        elif kind == "int":
            preset[key] = check_int(value, full, low=1, high=1000)
        else:
            preset[key] = check_choice(value, full, kind)
    return {"frame": CloudFrame(units=units, up=up, transform=transform), "preprocess": _preprocess_config(preset)}


def _preprocess_config(values: dict[str, Any]) -> Any:
    from pasta.perception import PreprocessConfig

    try:
        return PreprocessConfig(**values)
    except InputError as exc:  # e.g. crop_low not below crop_high: a config error, before any work
        raise ConfigError(str(exc)) from None


def prepare_input(loaded: Any, name: str, frame: Any, config: Any, perception: Any):
    """File points -> workspace frame -> :func:`pasta.perception.preprocess` -> :func:`prepare_cloud`.

    Returns ``(points (Q, 3) float32 to decompose, kept (P,) bool over the file's valid points, the kept
    points (K, 3) in the workspace frame)``. Without preprocessing, every point must lie in the workspace.
    """
    import numpy as np

    from pasta.perception import preprocess

    pts = frame.to_workspace(loaded.points)
    if not config.active:
        ready = prepare_cloud(pts.astype(np.float32), name, max_points=perception.max_points,
                              min_points=perception.min_points)
        return ready, np.ones(len(pts), bool), pts
    result = preprocess(pts, config)
    if result.kept.sum() == 0:
        raise InputError(f"{name} cloud: preprocessing dropped every one of its {len(pts)} points "
                         f"({_counts_text(result.counts)}); check units=, up=, transform= and preprocess.table_height")
    print(f"note: {name} cloud preprocessed: {len(pts):,} points, {_counts_text(result.counts)}, "
          f"{len(result.points):,} to decompose", file=sys.stderr)
    ready = prepare_cloud(result.points, name, max_points=perception.max_points, min_points=perception.min_points)
    return ready, result.kept, pts[result.kept]


def _counts_text(counts: dict[str, int]) -> str:
    words = {"cropped": "{n:,} outside the crop box", "table": "{n:,} on the table", "outliers": "{n:,} outliers",
             "filled": "{n:,} added to the table"}
    return ", ".join(words[k].format(n=v) for k, v in counts.items()) or "nothing changed"


def point_labels(loaded: Any, kept: Any, kept_points: Any, decomposed: Any, labels: Any):
    """Entity label of every point of the input file (``-1``: a hole or dropped by preprocessing), shaped
    like the file (``(N,)`` or ``(H, W)``).

    ``kept (P,)`` marks the file's valid points that preprocessing kept, ``kept_points (K, 3)`` are those in
    the workspace frame, ``decomposed (Q, 3)`` the cloud DBSCAN labelled with ``labels (Q,)``: each kept point
    takes the label of its nearest decomposed point (itself, unless voxel downsampling merged it)."""
    import numpy as np
    from scipy.spatial import cKDTree

    out = np.full(loaded.valid.shape, -1, dtype=np.int64)
    keep = np.flatnonzero(loaded.valid)[kept]
    if len(keep):
        _, nearest = cKDTree(decomposed).query(kept_points)
        out[keep] = labels[nearest]
    return out.reshape(loaded.shape)


def check_cpu_only(cfg: Any) -> None:
    """Refuse a device other than ``cpu``: the planners keep their tensors on the CPU, and the top-level
    ``device`` places learned policies (``pasta run`` / ``pasta eval``), which planning does not use."""
    for key in ("device", "encoder.device", "cost_model.device", "planner.device"):
        node = cfg
        for part in key.split("."):
            node = node.get(part) if hasattr(node, "get") else None
        if node is not None and str(node) != "cpu":
            raise ConfigError(f"{key}={node}: pasta plan runs on the CPU (its planners keep every tensor there; the "
                              "top-level device= places learned policies in pasta run / pasta eval); allowed: cpu")


def prepare_cloud(points, name: str, *, max_points: int, min_points: int):
    """Check a loaded cloud ``(P, 3)`` against the workspace and the size bounds; return ``(Q, 3)`` float32.

    Clouds above ``max_points`` are voxel-downsampled (:func:`pasta.core.decompose.voxel_downsample`) with
    one ``note:`` line on stderr. Raises :class:`InputError` for points outside :data:`WORKSPACE` or fewer
    than ``min_points`` points (before or after downsampling).
    """
    import numpy as np

    from pasta.core.decompose import voxel_downsample

    low, high = WORKSPACE
    outside = ~((points >= low) & (points <= high)).all(1)
    if outside.any():
        lo, hi = points.min(0), points.max(0)
        raise InputError(f"{name} cloud: {int(outside.sum())} of {len(points)} points lie outside the workspace, the "
                         f"unit cube [{low:g}, {high:g}]^3 (the cloud spans x {lo[0]:.3g}..{hi[0]:.3g}, "
                         f"y {lo[1]:.3g}..{hi[1]:.3g}, z {lo[2]:.3g}..{hi[2]:.3g}); express it in workspace "
                         "coordinates (metres, y up: units=, up=, transform=) or crop it (preprocess.crop=true)")
    if len(points) < min_points:
        raise InputError(f"{name} cloud has {len(points)} point(s); a cloud needs at least min_points={min_points} "
                         "(perception.min_points: the smallest entity decomposition keeps)")
    if len(points) <= max_points:
        return points
    small, voxel = voxel_downsample(points, max_points)
    print(f"note: {name} cloud has {len(points):,} points, more than perception.max_points={max_points:,}: voxel-downsampled "
          f"(voxel {voxel:.4f}) to {len(small):,} points before decomposition", file=sys.stderr)
    if len(small) < min_points:
        raise InputError(f"{name} cloud has {len(small)} point(s) after voxel downsampling; a cloud needs at least "
                         f"min_points={min_points}")
    return np.ascontiguousarray(small, dtype=np.float32)


def write_outputs(out: Path, plan_json: str, subgoals: list, counts: dict[str, int], *, labels: dict | None = None,
                  frame: Any = None) -> list[str]:
    """Write the sub-goal clouds (workspace frame ``step_{h}_subgoal.npy``; in the input's frame and units
    ``step_{h}_subgoal_input.npy`` when that differs), the per-point labels ``{obs,goal}_labels.npy``,
    ``entities.json`` and, last, ``plan.json`` (via a temporary name, so a ``plan.json`` present is a
    complete one); every file is written whole, never through a link (:mod:`pasta.core.files`); return the
    workspace sub-goal file names."""
    import functools
    import json

    import numpy as np

    from pasta.core.files import save_with, write_text

    out.mkdir(parents=True, exist_ok=True)
    (out / "plan.json").unlink(missing_ok=True)  # never leave an older plan beside these sub-goals
    files, inputs = [], []
    for h, clouds in enumerate(subgoals):
        path = out / f"step_{h}_subgoal.npy"
        save_with(path, functools.partial(np.save, arr=clouds))
        files.append(path.name)
        if frame is not None and not frame.identity:
            path = out / f"step_{h}_subgoal_input.npy"
            save_with(path, functools.partial(np.save, arr=frame.from_workspace(clouds).astype(np.float32)))
            inputs.append(path.name)
        else:
            (out / f"step_{h}_subgoal_input.npy").unlink(missing_ok=True)
    extra: dict[str, Any] = {"subgoals": files}
    if inputs:
        extra["subgoals_input_frame"] = inputs
    for name, lab in (labels or {}).items():
        save_with(out / f"{name}_labels.npy", functools.partial(np.save, arr=lab))
        extra[f"{name}_labels"] = f"{name}_labels.npy"
    write_text(out / "entities.json", json.dumps({**counts, **extra}, indent=2))
    write_text(out / "plan.json", plan_json)
    return files
