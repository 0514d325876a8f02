"""``pasta plan obs=FILE goal=FILE [key=value ...]``: plan from two point-cloud files, no simulator.

Each cloud (``.npy`` ``(P, 3)`` or organised ``(H, W, 3)`` with NaN holes, PLY ascii or binary) is put in
the workspace frame (``units=``, ``up=``, ``transform=``), optionally preprocessed (``preprocess=camera``
and ``preprocess.*``: :mod:`pasta.perception`), decomposed into entities
(:func:`pasta.core.decompose.decompose_labels`, ``decompose.eps`` / ``decompose.min_samples``), encoded
with the configured encoder, checked against the encoder's box of training centroids, and planned with
the configured planner. Writes ``plan.json`` (with ``info.confidence`` and ``info.flags``), per step
``h`` the decoded sub-goal entities ``step_{h}_subgoal.npy`` ``(M_h, P, 3)`` (workspace frame) and, for
another input frame, ``step_{h}_subgoal_input.npy`` (the input's frame and units), and the per-point
entity labels ``obs_labels.npy`` / ``goal_labels.npy`` (shaped like the input, ``-1`` for dropped
points) to ``out=DIR``. Exit codes: 0 a plan, 2 bad input or config, 3 a plan written but flagged
unreachable (docs/real_world.md).

Hardened against hostile inputs (issue 21): ``out=`` and every command key are checked before anything
is computed; clouds above ``max_points`` are voxel-downsampled before DBSCAN (whose memory grows with
the square of a dense cloud's size); clouds must lie in the unit-cube workspace and hold at least
``min_points`` points; encoded latents, the plan (:meth:`pasta.core.Plan.check`) and the decoded
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

HELP = ("plan from an observed and a goal point cloud (.npy or .ply): obs=FILE goal=FILE [out=DIR] [threads=1] "
        "[max_points=10000] [units=m|mm] [up=y|z] [transform=FILE] [preprocess=none|camera] [planner=NAME ...]")

#: keys of this command (the rest are run-config overrides)
COMMAND_KEYS = {
    "obs": None,
    "goal": None,
    "out": "plan_out",
    "models": "",  # root of trained networks (`pasta train ... out=DIR`); empty: the shipped weights (pasta.weights)
    "horizon": "3",
    "skills": "",  # comma-separated skill names (default: every registered skill with trained weights)
    "skeleton": "",  # optional fixed skill sequence, comma-separated
    "num_points": "1000",  # points per entity after decomposition and per decoded sub-goal entity
    "min_points": "50",  # DBSCAN clusters smaller than this are noise (the paper's planning value)
    # clouds with more points are voxel-downsampled to at most this many before decomposition: DBSCAN
    # took 6 GB on 1e5 points; 10,000 leaves the usual 1,000-5,000-point clouds untouched
    "max_points": "10000",
    # torch CPU threads (0: torch's default). 1 as in `pasta run`: 16 s instead of 152 s on a busy machine
    "threads": "1",
    # the input contract (docs/real_world.md): units, up axis and an optional 4x4 camera-to-workspace matrix
    "units": "m",
    "up": "y",
    "transform": "",
    # preprocessing (pasta.perception.preprocess): a preset, then single keys over it ("" = the preset's value)
    "preprocess": "none",
    **{f"preprocess.{k}": "" for k in ("crop", "crop_low", "crop_high", "table", "table_height", "table_margin",
                                        "outliers", "outlier_k", "outlier_std", "complete", "fill_spacing")},
    # DBSCAN of the decomposition (pasta.core.decompose)
    "decompose.eps": "0.03",
    "decompose.min_samples": "6",
    # checks of the contract and of the result (docs/real_world.md, "Confidence and exit codes")
    "check.box_margin": "0.01",  # entity centroids may lie this far (metres) outside the training box
    "check.min_feasibility": "0.5",  # a step below: the plan is flagged unreachable (exit code 3)
    "check.max_cost": "0.01",  # a final set cost above: unreachable (exit code 3)
    # |z| above (Mahalanobis distance under the prior N(0, I)): out of distribution (a warning only); entities
    # of the validation seeds 2000-2002 (crs, cut_rearrange) reach 2.94 (full clouds) and 3.28 (camera views)
    "check.max_z": "4.0",
}

#: exit code of a plan that was written but is flagged unreachable (2 is bad input or config)
EXIT_UNREACHABLE = 3

#: ranges of the integer command keys (inclusive): a horizon above 10 enumerates 3**10+ sequences; fewer
#: than 16 points per entity cannot describe a piece's shape, and more than 10,000 only slow the encoder
#: (it reads at most ``encode_points`` of them)
INT_RANGES = {"horizon": (1, 10), "num_points": (16, 10_000), "min_points": (1, None), "max_points": (1, None),
              "threads": (0, None)}

#: a cloud file with more points is refused before it is read (loading and downsampling cost ~80 bytes
#: a point); downsample such clouds before `pasta plan`
MAX_FILE_POINTS = 10_000_000

#: the workspace every cloud must lie in (the simulator's unit cube, y up)
WORKSPACE = (0.0, 1.0)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("overrides", nargs="*", metavar="key=value",
                        help="obs=FILE goal=FILE out=DIR models=DIR horizon=H (1-10) skills=a,b skeleton=a,b,c "
                             "num_points=1000 min_points=50 max_points=10000 threads=1 units=m|mm up=y|z "
                             "transform=FILE preprocess=none|camera preprocess.KEY=V decompose.eps=0.03 "
                             "decompose.min_samples=6 check.KEY=V (docs/real_world.md), and any config override "
                             "(seed=S planner=sampling planner.num_samples=2000 encoder=NAME cost_model=NAME)")


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
    from pasta.config.validate import check_output_dir

    mine, overrides = split_arguments(list(items))
    opts = command_options(mine)
    camera = camera_options(mine)
    out = check_output_dir(mine["out"], "out")  # before anything is computed: a bad out= must not cost a plan
    import numpy as np
    import torch

    if opts["threads"] > 0:
        torch.set_num_threads(opts["threads"])
    from pasta.config import load_config, section
    from pasta.core import PlanningProblem
    from pasta.core.decompose import decompose_labels, resample
    from pasta.core.shapes import check_latents
    from pasta.execute.skillset import choose_skills, needs_feasibility_network
    from pasta.planning.batch import training_boxes

    if plugins is None:
        from pasta.plugins import get_plugins

        plugins = get_plugins()
    from pasta.weights import models_root, weight_overrides

    root = models_root(mine["models"])
    if mine["models"]:  # the encoder and cost weights under the given root unless set explicitly
        overrides += weight_overrides(root, overrides)
    cfg = load_config(overrides, plugins=plugins)
    check_cpu_only(cfg)
    num_points, min_points, seed = opts["num_points"], opts["min_points"], int(cfg.seed)
    frame = camera["frame"]
    loaded, clouds, kept, kept_points = {}, {}, {}, {}
    for name in ("obs", "goal"):
        loaded[name] = read_cloud(mine[name], name)
        clouds[name], kept[name], kept_points[name] = prepare_input(loaded[name], name, frame, camera["preprocess"],
                                                 max_points=opts["max_points"], min_points=min_points)

    encoder = plugins.encoders.create(cfg.encoder.name, section(cfg, "encoder"))
    cost = plugins.cost_models.create(cfg.cost_model.name, section(cfg, "cost_model"))
    choice = choose_skills(mine["skills"] or None, root, plugins=plugins)  # the same rule as `pasta run`
    if choice.warning():
        print(choice.warning(), file=sys.stderr)
    skeleton = tuple(n for n in mine["skeleton"].split(",") if n) or None
    choice.require(skeleton or (), "skeleton=")
    skills = [plugins.skills.create(n) for n in choice.names]
    needs = [s for s in skills if needs_feasibility_network(s)]
    if needs:
        from pasta.nn.loading import attach_feasibility

        attach_feasibility(needs, root, latent_dim=encoder.latent_dim)
    entities, labels = {}, {}
    for name, pts in clouds.items():  # decompose(), keeping the labels for the per-point output
        lab = decompose_labels(pts, eps=camera["eps"], min_samples=camera["min_samples"], min_points=min_points)
        rng = np.random.default_rng(seed)
        entities[name] = [resample(pts[lab == k], num_points, rng) for k in range(int(lab.max()) + 1)]
        labels[name] = point_labels(loaded[name], kept[name], kept_points[name], pts, lab)
    latents = {}
    boxes = training_boxes(encoder, skills)
    with torch.no_grad():
        for name, ents in entities.items():
            u = encoder.encode(torch.from_numpy(np.stack(ents))).float()
            latents[name] = check_latents(u, f"the {len(ents)} encoded {name} entities (encoder {cfg.encoder.name!r})",
                                          dim=encoder.latent_dim)
            check_training_box(latents[name], encoder, name, camera["box_margin"], boxes=boxes)
    # observed pieces that already are a goal piece (Chamfer < 5e-4): never attended, matched to it
    from pasta.core.matching import unchanged_pairs

    fixed = unchanged_pairs(np.stack(entities["obs"]), np.stack(entities["goal"]))
    problem = PlanningProblem(latents["obs"], latents["goal"], skills, encoder, cost, horizon=opts["horizon"],
                              seed=seed, skeleton=skeleton, fixed=tuple(fixed))
    planner = plugins.planners.create(cfg.planner.name, section(cfg, "planner"))
    plan = planner.plan(problem).check()  # a NaN or out-of-range score/latent is an error, not a plan
    report = confidence(plan, encoder, latents, camera, skills)
    plan = dataclasses.replace(plan, info={**plan.info, "confidence": report["confidence"], "flags": report["flags"],
                                           "input": {"frame": frame.describe(),
                                                     "preprocess": camera["preprocess"].to_dict(),
                                                     "decompose": {"eps": camera["eps"],
                                                                   "min_samples": camera["min_samples"],
                                                                   "min_points": min_points}}})
    text = plan.to_json()
    subgoals = []
    with torch.no_grad():
        for h, step in enumerate(plan.steps):
            clouds_h = encoder.decode(torch.tensor(step.subgoal, dtype=torch.float32), num_points).cpu().numpy()
            if not np.isfinite(clouds_h).all():
                raise InputError(f"plan step {h + 1} ({step.skill}): the encoder {cfg.encoder.name!r} decodes its "
                                 "sub-goal latents to NaN or infinite points")
            subgoals.append(clouds_h.astype(np.float32))
    files = write_outputs(out, text, subgoals, {"obs": len(entities["obs"]), "goal": len(entities["goal"])},
                          labels=labels, frame=frame)
    print(plan.summary())
    for flag in report["flags"]:
        print(f"warning: {flag['kind']}: {flag['message']}", file=sys.stderr)
    print(f"wrote {out / 'plan.json'} and {len(files)} sub-goal clouds to {out}")
    if any(f["kind"] == "unreachable" for f in report["flags"]):
        return EXIT_UNREACHABLE
    return 0


def camera_options(mine: dict[str, str]) -> dict[str, Any]:
    """The input-contract, preprocessing, decomposition and check keys, validated (one-line ConfigError)."""
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
    return {
        "frame": CloudFrame(units=units, up=up, transform=transform),
        "preprocess": _preprocess_config(preset),
        "eps": check_number(mine["decompose.eps"], "decompose.eps", low=0.0, low_open=True, high=1.0),
        "min_samples": check_int(mine["decompose.min_samples"], "decompose.min_samples", low=1, high=10_000),
        "box_margin": check_number(mine["check.box_margin"], "check.box_margin", low=0.0, high=1.0),
        "min_feasibility": check_number(mine["check.min_feasibility"], "check.min_feasibility", low=0.0, high=1.0),
        "max_cost": check_number(mine["check.max_cost"], "check.max_cost", low=0.0, low_open=True),
        "max_z": check_number(mine["check.max_z"], "check.max_z", low=0.0, low_open=True),
    }


def _preprocess_config(values: dict[str, Any]) -> Any:
    from pasta.perception import PreprocessConfig

    try:
        return PreprocessConfig(**values)
    except InputError as exc:  # e.g. crop_low not below crop_high: a config error, before any work
        raise ConfigError(str(exc)) from None


def prepare_input(loaded: Any, name: str, frame: Any, config: Any, *, max_points: int, min_points: int):
    """File points -> workspace frame -> :func:`pasta.perception.preprocess` -> :func:`prepare_cloud`.

    Returns ``(points (Q, 3) float32 to decompose, kept (P,) bool over the file's valid points, the kept
    points (K, 3) in the workspace frame)``. Without preprocessing, every point must lie in the workspace.
    """
    import numpy as np

    from pasta.perception import preprocess

    pts = frame.to_workspace(loaded.points)
    if not config.active:
        ready = prepare_cloud(pts.astype(np.float32), name, max_points=max_points, min_points=min_points)
        return ready, np.ones(len(pts), bool), pts
    result = preprocess(pts, config)
    if result.kept.sum() == 0:
        raise InputError(f"{name} cloud: preprocessing dropped every one of its {len(pts)} points "
                         f"({_counts_text(result.counts)}); check units=, up=, transform= and preprocess.table_height")
    print(f"note: {name} cloud preprocessed: {len(pts):,} points, {_counts_text(result.counts)}, "
          f"{len(result.points):,} to decompose", file=sys.stderr)
    ready = prepare_cloud(result.points, name, max_points=max_points, min_points=min_points)
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


def _outside(t: Any, boxes: Any, margin: float = 0.0) -> tuple[Any, Any]:
    """Per centroid ``t (K, 3)``: the per-axis distance ``(K, 3)`` outside its nearest box (more than
    ``margin`` out), and that box's index ``(K,)``."""
    import numpy as np

    per_box = np.stack([np.maximum(np.asarray(lo) - margin - t, 0) + np.maximum(t - np.asarray(hi) - margin, 0)
                        for lo, hi in boxes])  # (B, K, 3)
    nearest = np.argmin(np.linalg.norm(per_box, axis=2), axis=0)
    return per_box[nearest, np.arange(len(t))], nearest


def check_training_box(latents: Any, encoder: Any, name: str, margin: float, boxes: Any = None) -> None:
    """Refuse entities whose centroid ``t`` lies more than ``margin`` outside every box of ``boxes``
    (default: the encoder's box of training centroids; :func:`pasta.planning.batch.training_boxes` adds the
    skills' own): the planner clamps sub-goals into these boxes, so such a plan is silently wrong."""
    import numpy as np

    t = latents[:, encoder.z_dim:].detach().cpu().numpy().astype(np.float64)
    boxes = boxes or [(encoder.t_low, encoder.t_high)]
    outside, nearest = _outside(t, boxes, margin)
    bad = np.flatnonzero(outside.max(1) > 0)
    if len(bad):
        k = int(bad[np.argmax(outside[bad].max(1))])
        axis = "xyz"[int(np.argmax(outside[k]))]
        low, high = boxes[int(nearest[k])]
        box = ", ".join(f"{a} {lo:.3f}..{hi:.3f}" for a, lo, hi in zip("xyz", low, high))
        more = f" (the nearest of {len(boxes)}: the encoder's and the skills' own)" if len(boxes) > 1 else ""
        raise InputError(f"{name} cloud: {len(bad)} of {len(t)} pieces lie outside the box the models were trained on "
                         f"(piece {k} centroid ({t[k, 0]:.3f}, {t[k, 1]:.3f}, {t[k, 2]:.3f}) is {outside[k].max():.3f} "
                         f"out in {axis}; box {box}{more}, check.box_margin={margin:g}); a top-down camera view needs "
                         "preprocess=camera, another frame units=, up=, transform=")


def latent_distances(latents: Any, encoder: Any, boxes: Any = None) -> list[dict[str, float]]:
    """Per latent ``(K, D)``: ``z_norm`` (Mahalanobis distance of ``z`` under the prior N(0, I)) and
    ``t_outside`` (metres of ``t`` outside the nearest of ``boxes``, default the encoder's box of training
    centroids; 0 inside one)."""
    import numpy as np

    u = np.asarray(latents, dtype=np.float64).reshape(-1, encoder.latent_dim)
    z, t = u[:, :encoder.z_dim], u[:, encoder.z_dim:]
    out = np.linalg.norm(_outside(t, boxes or [(encoder.t_low, encoder.t_high)])[0], axis=1)
    return [{"z_norm": round(float(a), 6), "t_outside": round(float(b), 6)} for a, b in zip(np.linalg.norm(z, axis=1), out)]


def confidence(plan: Any, encoder: Any, latents: dict, camera: dict, skills: Any = ()) -> dict[str, Any]:
    """How far the plan's latents sit from the training distribution, and the flags it raises.

    Returns ``{"confidence": {...}, "flags": [{"kind", "message"}, ...]}``; kind ``unreachable`` (a step's
    feasibility below ``check.min_feasibility`` or the final cost above ``check.max_cost``: exit code 3) or
    ``out_of_distribution`` (a latent with ``|z|`` above ``check.max_z``: a warning).
    """
    from pasta.planning.batch import centroid_box, training_boxes

    boxes = training_boxes(encoder, skills)
    by_name = {sk.name: sk for sk in skills}
    conf: dict[str, Any] = {name: latent_distances(latents[name], encoder, boxes) for name in ("obs", "goal")}
    steps = []
    for step in plan.steps:
        own = [centroid_box(encoder, by_name[step.skill])] if step.skill in by_name else None
        d = latent_distances(step.subgoal, encoder, own)
        steps.append({"skill": step.skill, "feasibility": step.feasibility,
                      "z_norm": max(x["z_norm"] for x in d), "t_outside": max(x["t_outside"] for x in d)})
    conf["steps"] = steps
    conf["min_feasibility"] = min((s["feasibility"] for s in steps), default=1.0)
    conf["final_cost"] = plan.final_cost
    flags = []
    low = [f"{h + 1} ({s['skill']}) {s['feasibility']:.3f}" for h, s in enumerate(steps)
           if s["feasibility"] < camera["min_feasibility"]]
    if low:
        flags.append({"kind": "unreachable", "message": f"predicted feasibility below check.min_feasibility="
                      f"{camera['min_feasibility']:g} at step {', '.join(low)}"})
    if plan.final_cost > camera["max_cost"]:
        flags.append({"kind": "unreachable", "message": f"the final state is predicted {plan.final_cost:.4f} "
                      f"(Chamfer) from the goal, above check.max_cost={camera['max_cost']:g}"})
    far = [f"{where} {x['z_norm']:.2f}" for where, xs in (("obs", conf["obs"]), ("goal", conf["goal"]),
                                                         *((f"step {h + 1}", [s]) for h, s in enumerate(steps)))
           for x in xs if x["z_norm"] > camera["max_z"]]
    if far:
        flags.append({"kind": "out_of_distribution", "message": f"|z| above check.max_z={camera['max_z']:g} "
                      f"(prior N(0, I)): {', '.join(far)}"})
    return {"confidence": conf, "flags": flags}



def command_options(mine: dict[str, str]) -> dict[str, int]:
    """The integer command keys, range-checked (:data:`INT_RANGES`); ``max_points >= min_points``."""
    from pasta.config.validate import check_int

    opts = {key: check_int(mine[key], key, low=low, high=high) for key, (low, high) in INT_RANGES.items()}
    if opts["max_points"] < opts["min_points"]:
        raise ConfigError(f"max_points={opts['max_points']}: must be >= min_points ({opts['min_points']}), or no "
                          "downsampled cloud could hold one entity")
    return opts


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
                         "(the smallest entity decomposition keeps)")
    if len(points) <= max_points:
        return points
    small, voxel = voxel_downsample(points, max_points)
    print(f"note: {name} cloud has {len(points):,} points, more than max_points={max_points:,}: voxel-downsampled "
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
    complete one); return the workspace sub-goal file names."""
    import json
    import os

    import numpy as np

    out.mkdir(parents=True, exist_ok=True)
    (out / "plan.json").unlink(missing_ok=True)  # never leave an older plan beside these sub-goals
    files, inputs = [], []
    for h, clouds in enumerate(subgoals):
        path = out / f"step_{h}_subgoal.npy"
        np.save(path, clouds)
        files.append(path.name)
        if frame is not None and not frame.identity:
            path = out / f"step_{h}_subgoal_input.npy"
            np.save(path, frame.from_workspace(clouds).astype(np.float32))
            inputs.append(path.name)
        else:
            (out / f"step_{h}_subgoal_input.npy").unlink(missing_ok=True)
    extra: dict[str, Any] = {"subgoals": files}
    if inputs:
        extra["subgoals_input_frame"] = inputs
    for name, lab in (labels or {}).items():
        np.save(out / f"{name}_labels.npy", lab)
        extra[f"{name}_labels"] = f"{name}_labels.npy"
    (out / "entities.json").write_text(json.dumps({**counts, **extra}, indent=2))
    tmp = out / "plan.json.tmp"
    tmp.write_text(plan_json)
    os.replace(tmp, out / "plan.json")
    return files
