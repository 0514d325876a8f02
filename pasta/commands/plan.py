"""``pasta plan obs=FILE goal=FILE [key=value ...]``: plan from two point-cloud files, no simulator.

Each cloud (``.npy`` ``(P, 3)`` or ASCII ``.ply``) is decomposed into entities
(:func:`pasta.core.decompose.decompose`), encoded with the configured encoder, and planned with the
configured planner. Writes ``plan.json`` and, per step ``h``, the decoded sub-goal entities
``step_{h}_subgoal.npy`` ``(M_h, P, 3)`` to ``out=DIR``.

Hardened against hostile inputs (issue 21): ``out=`` and every command key are checked before anything
is computed; clouds above ``max_points`` are voxel-downsampled before DBSCAN (whose memory grows with
the square of a dense cloud's size); clouds must lie in the unit-cube workspace and hold at least
``min_points`` points; encoded latents, the plan (:meth:`pasta.core.Plan.check`) and the decoded
sub-goals are checked for NaN and ranges before anything is written, and ``plan.json`` (strict JSON) is
written last, under a temporary name renamed into place.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from pasta.core.errors import ConfigError, InputError

HELP = ("plan from an observed and a goal point cloud (.npy or ASCII .ply): obs=FILE goal=FILE [out=DIR] [threads=1] "
        "[max_points=10000] [planner=NAME ...]")

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
}

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
                             "num_points=1000 min_points=50 max_points=10000 threads=1, and any config override "
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
    """Read a ``(P, 3)`` float32 point cloud from ``.npy`` or ASCII ``.ply``; bad files raise InputError."""
    import numpy as np

    from pasta.core.shapes import check_points

    p = Path(path)
    if not p.is_file():
        raise InputError(f"{name} file {str(p)!r} does not exist")
    suffix = p.suffix.lower()
    try:
        if suffix == ".npy":
            header = np.load(p, mmap_mode="r", allow_pickle=False)  # reads the shape, not the data
            _check_file_size(len(header) if header.ndim else 0, name, p)
            del header
            arr = np.load(p, allow_pickle=False)
        elif suffix == ".ply":
            arr = _read_ascii_ply(p, name)
        else:
            raise InputError(f"{name} file {str(p)!r}: unsupported extension {suffix!r}; use .npy or ASCII .ply")
    except InputError:
        raise
    except Exception as exc:  # noqa: BLE001 - any parse failure becomes a clear input error
        raise InputError(f"{name} file {str(p)!r} cannot be read: {exc}") from None
    arr = np.asarray(arr)
    if arr.dtype.kind not in "fiu":
        raise InputError(f"{name} file {str(p)!r} must hold numbers, got dtype {arr.dtype}")
    check_points(arr, f"{name} cloud {p.name}")
    return np.ascontiguousarray(arr, dtype=np.float32)


def _check_file_size(count: int, name: str, path: Path) -> None:
    if count > MAX_FILE_POINTS:
        raise InputError(f"{name} file {str(path)!r} has {count:,} points, more than pasta plan reads "
                         f"({MAX_FILE_POINTS:,}); downsample it first (max_points= bounds what reaches decomposition)")


def _read_ascii_ply(path: Path, name: str = "cloud"):
    import numpy as np

    lines = path.read_text(errors="replace").splitlines()
    if not lines or lines[0].strip() != "ply":
        raise InputError(f"{str(path)!r} is not a PLY file (no 'ply' magic line)")
    count, props, in_vertex, fmt, body = 0, [], False, None, None
    for i, line in enumerate(lines[1:], 1):
        words = line.split()
        if not words:
            continue
        if words[0] == "format":
            fmt = words[1]
        elif words[0] == "element":
            in_vertex = words[1] == "vertex"
            if in_vertex:
                count = int(words[2])
                _check_file_size(count, name, path)
        elif words[0] == "property" and in_vertex:
            props.append(words[-1])
        elif words[0] == "end_header":
            body = i + 1
            break
    if fmt != "ascii":
        raise InputError(f"{str(path)!r}: only ASCII PLY is supported, got format {fmt!r}")
    if body is None or not {"x", "y", "z"} <= set(props):
        raise InputError(f"{str(path)!r}: PLY header must declare vertex properties x, y, z")
    if count == 0:
        return np.zeros((0, 3))
    rows = lines[body : body + count]
    expected = f"{str(path)!r}: expected {count} vertex rows of {len(props)} values"
    if len(rows) != count:
        raise InputError(expected)
    try:  # numpy's C parser: a 1e6-point file without a Python list per row
        data = np.loadtxt(rows, dtype=np.float64, ndmin=2, usecols=[props.index(c) for c in "xyz"])
    except ValueError:
        raise InputError(expected) from None
    return data.reshape(-1, 3)


def run(args: argparse.Namespace) -> int:
    return plan_files(args.overrides)


def plan_files(items: list[str], *, plugins: Any = None) -> int:
    """Run ``pasta plan`` on ``key=value`` items; return the exit code (errors raise :class:`PastaError`)."""
    from pasta.config.validate import check_output_dir

    mine, overrides = split_arguments(list(items))
    opts = command_options(mine)
    out = check_output_dir(mine["out"], "out")  # before anything is computed: a bad out= must not cost a plan
    import numpy as np
    import torch

    if opts["threads"] > 0:
        torch.set_num_threads(opts["threads"])
    from pasta.config import load_config, section
    from pasta.core import PlanningProblem
    from pasta.core.decompose import decompose
    from pasta.core.shapes import check_latents
    from pasta.execute.skillset import choose_skills, needs_feasibility_network

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
    clouds = {}
    for name in ("obs", "goal"):
        clouds[name] = prepare_cloud(load_cloud(mine[name], name), name, max_points=opts["max_points"],
                                     min_points=min_points)

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
    entities = {name: decompose(pts, min_points=min_points, num_points=num_points, seed=seed)
                for name, pts in clouds.items()}
    latents = {}
    with torch.no_grad():
        for name, ents in entities.items():
            u = encoder.encode(torch.from_numpy(np.stack(ents))).float()
            latents[name] = check_latents(u, f"the {len(ents)} encoded {name} entities (encoder {cfg.encoder.name!r})",
                                          dim=encoder.latent_dim)
    # observed pieces that already are a goal piece (Chamfer < 5e-4): never attended, matched to it
    from pasta.core.matching import unchanged_pairs

    fixed = unchanged_pairs(np.stack(entities["obs"]), np.stack(entities["goal"]))
    problem = PlanningProblem(latents["obs"], latents["goal"], skills, encoder, cost, horizon=opts["horizon"],
                              seed=seed, skeleton=skeleton, fixed=tuple(fixed))
    planner = plugins.planners.create(cfg.planner.name, section(cfg, "planner"))
    plan = planner.plan(problem).check()  # a NaN or out-of-range score/latent is an error, not a plan
    text = plan.to_json()
    subgoals = []
    with torch.no_grad():
        for h, step in enumerate(plan.steps):
            clouds_h = encoder.decode(torch.tensor(step.subgoal, dtype=torch.float32), num_points).cpu().numpy()
            if not np.isfinite(clouds_h).all():
                raise InputError(f"plan step {h + 1} ({step.skill}): the encoder {cfg.encoder.name!r} decodes its "
                                 "sub-goal latents to NaN or infinite points")
            subgoals.append(clouds_h.astype(np.float32))
    files = write_outputs(out, text, subgoals, {"obs": len(entities["obs"]), "goal": len(entities["goal"])})
    print(plan.summary())
    print(f"wrote {out / 'plan.json'} and {len(files)} sub-goal clouds to {out}")
    return 0


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
                         "coordinates (metres, y up)")
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


def write_outputs(out: Path, plan_json: str, subgoals: list, counts: dict[str, int]) -> list[str]:
    """Write the sub-goal clouds, ``entities.json`` and, last, ``plan.json`` (via a temporary name, so a
    ``plan.json`` present is a complete one); return the sub-goal file names."""
    import json
    import os

    import numpy as np

    out.mkdir(parents=True, exist_ok=True)
    (out / "plan.json").unlink(missing_ok=True)  # never leave an older plan beside these sub-goals
    files = []
    for h, clouds in enumerate(subgoals):
        path = out / f"step_{h}_subgoal.npy"
        np.save(path, clouds)
        files.append(path.name)
    (out / "entities.json").write_text(json.dumps({**counts, "subgoals": files}, indent=2))
    tmp = out / "plan.json.tmp"
    tmp.write_text(plan_json)
    os.replace(tmp, out / "plan.json")
    return files

