"""``pasta plan obs=FILE goal=FILE [key=value ...]``: plan from two point-cloud files, no simulator.

Each cloud (``.npy`` ``(P, 3)`` or ASCII ``.ply``) is decomposed into entities
(:func:`pasta.core.decompose.decompose`), encoded with the configured encoder, and planned with the
configured planner. Writes ``plan.json`` and, per step ``h``, the decoded sub-goal entities
``step_{h}_subgoal.npy`` ``(M_h, P, 3)`` to ``out=DIR``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from pasta.core.errors import ConfigError, InputError

HELP = "plan from an observed and a goal point cloud (.npy or ASCII .ply): obs=FILE goal=FILE [out=DIR] [planner=NAME ...]"

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
}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("overrides", nargs="*", metavar="key=value",
                        help="obs=FILE goal=FILE out=DIR models=DIR horizon=H skills=a,b skeleton=a,b,c, and any "
                             "config override (planner=sampling planner.num_samples=2000 encoder=NAME cost_model=NAME)")


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
            arr = np.load(p, allow_pickle=False)
        elif suffix == ".ply":
            arr = _read_ascii_ply(p)
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


def _read_ascii_ply(path: Path):
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
        elif words[0] == "property" and in_vertex:
            props.append(words[-1])
        elif words[0] == "end_header":
            body = i + 1
            break
    if fmt != "ascii":
        raise InputError(f"{str(path)!r}: only ASCII PLY is supported, got format {fmt!r}")
    if body is None or not {"x", "y", "z"} <= set(props):
        raise InputError(f"{str(path)!r}: PLY header must declare vertex properties x, y, z")
    rows = [ln.split() for ln in lines[body : body + count]]
    if len(rows) != count or any(len(r) < len(props) for r in rows):
        raise InputError(f"{str(path)!r}: expected {count} vertex rows of {len(props)} values")
    data = np.array([[float(r[props.index(c)]) for c in "xyz"] for r in rows], dtype=np.float64)
    return data.reshape(-1, 3)


def run(args: argparse.Namespace) -> int:
    return plan_files(args.overrides)


def plan_files(items: list[str], *, plugins: Any = None) -> int:
    import json

    import numpy as np
    import torch

    from pasta.config import load_config, section
    from pasta.core import PlanningProblem
    from pasta.core.decompose import decompose
    from pasta.execute.skillset import choose_skills, needs_feasibility_network

    if plugins is None:
        from pasta.plugins import get_plugins

        plugins = get_plugins()
    from pasta.weights import models_root, weight_overrides

    mine, overrides = split_arguments(list(items))
    root = models_root(mine["models"])
    if mine["models"]:  # the encoder and cost weights under the given root unless set explicitly
        overrides += weight_overrides(root, overrides)
    cfg = load_config(overrides, plugins=plugins)
    num_points, min_points = _int(mine, "num_points"), _int(mine, "min_points")
    obs_pts, goal_pts = load_cloud(mine["obs"], "obs"), load_cloud(mine["goal"], "goal")

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
    obs_entities = decompose(obs_pts, min_points=min_points, num_points=num_points, seed=int(cfg.seed))
    goal_entities = decompose(goal_pts, min_points=min_points, num_points=num_points, seed=int(cfg.seed))
    with torch.no_grad():
        obs = encoder.encode(torch.from_numpy(np.stack(obs_entities))).float()
        goal = encoder.encode(torch.from_numpy(np.stack(goal_entities))).float()
    problem = PlanningProblem(obs, goal, skills, encoder, cost, horizon=_int(mine, "horizon"), seed=int(cfg.seed), skeleton=skeleton)
    planner = plugins.planners.create(cfg.planner.name, section(cfg, "planner"))
    plan = planner.plan(problem)
    out = Path(mine["out"])
    out.mkdir(parents=True, exist_ok=True)
    (out / "plan.json").write_text(plan.to_json())
    files = []
    with torch.no_grad():
        for h, step in enumerate(plan.steps):
            clouds = encoder.decode(torch.tensor(step.subgoal, dtype=torch.float32), num_points).cpu().numpy()
            path = out / f"step_{h}_subgoal.npy"
            np.save(path, clouds.astype(np.float32))
            files.append(path.name)
    (out / "entities.json").write_text(json.dumps({"obs": len(obs_entities), "goal": len(goal_entities), "subgoals": files}, indent=2))
    print(plan.summary())
    print(f"wrote {out / 'plan.json'} and {len(files)} sub-goal clouds to {out}")
    return 0


def _int(mine: dict[str, str], key: str) -> int:
    try:
        return int(mine[key])
    except ValueError:
        raise ConfigError(f"{key} must be an integer, got {mine[key]!r}") from None
