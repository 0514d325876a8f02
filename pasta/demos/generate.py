"""Demonstration generation: scripted experts with random parameters on the scenes their skills draw, or
gradient-based trajectory optimisation (GBTO) toward the targets they draw.

Any registered skill whose plugin defines the demonstration hooks (:meth:`pasta.core.Skill.has_expert`:
``demo_scene``, ``sample_expert_params``, ``expert_approach_pose``, ``expert``) can make demonstrations;
the scene (``n_in`` boxes of dough) comes from its ``demo_scene``, see :mod:`pasta.demos.scene`. A skill without
a scripted expert that defines ``demo_target`` (:meth:`pasta.core.Skill.has_gbto`) makes them by GBTO
(``expert=trajopt``, the default for such a skill): from its approach pose toward the drawn target, Adam on
``trajopt_steps`` actions through the differentiable simulator (:func:`pasta.sim.trajopt.optimise_moves`, as the
paper's demonstrations were made), and the best actions are then executed and recorded like an expert's.

Layout of a dataset directory (fixed; the trainers read it)::

    DIR/manifest.json                 config, versions, per-skill counts
    DIR/<skill>/demo_00000.npz        one demonstration (np.load(..., allow_pickle=False))
        dough        (T+1, P, 3) float32  observed dough before every step and after the last
                                          (the same P particles every step)
        tool_points  (T+1, Tp, 3) float32 the skill's tool surface points
        tool_pose    (T+1, 7) float32     tool position + quaternion (w, x, y, z)
        action       (T, A) float32       actions in [-1, 1]
        skill        0-d str
        params       0-d str, JSON of the expert parameters (GBTO: its losses and best iteration)
        final_dough  (P, 3) float32       the dough after the idle steps that follow the skill
        dough_index  (P,) int64           simulator particle indices of the observed points

Demo ``i`` of a skill depends only on (seed, skill, i), so runs are reproducible and resumable: files
that exist are skipped, and each file is written under a temporary name and renamed when complete.
Demos are made by :func:`pasta.distributed.map_jobs`: in this process, in local worker processes
(``spawn``, each with its own Taichi runtime; a worker that dies is replaced and its demo retried, workers
die with the parent: :mod:`pasta.distributed.local`) or as Ray tasks (``backend=ray``,
:mod:`pasta.distributed.ray_backend`). Only this process writes the files, whatever made the arrays. A
worker still on one demo after ``deadline_s`` seconds (default :func:`demo_deadline`, from the skill's
step limit) is given up and the demo retried, as after a death.
"""

from __future__ import annotations

import json
import os
import platform
import time
import zlib
from dataclasses import asdict, dataclass
from importlib import metadata
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from pasta.core.errors import ConfigError
from pasta.core.files import OutputLock, write_json
from pasta.demos.workers import MAX_ATTEMPTS, DemoWorkerError
from pasta.distributed import MAX_WORKERS, BackendConfig, BackendError
from pasta.demos.scene import (DEFAULT, check_demo_skill, check_variant, demo_skills, scene_boxes, scene_particles,
                               variant_config)

if TYPE_CHECKING:
    from pasta.core import Skill

FORMAT = "pasta-demos/1"
#: bounds of the counts of ``pasta demos`` (more is a typo, not a dataset)
MAX_DEMOS = 1_000_000
MAX_IDLE = 100_000
#: the training stages that read demonstrations (:attr:`pasta.core.DemoVariant.stages` names some of them)
TRAINING_STAGES = ("vae", "feasibility", "cost", "policy", "reset")


@dataclass
class DemoConfig:
    """Arguments of ``pasta demos`` (``key=value``).

    Attributes:
        skill: registered skill that can make demonstrations (:func:`pasta.demos.scene.demo_skills`).
        num: demonstrations to have in ``out/<skill>`` (existing ones are kept).
        out: dataset directory.
        workers: worker processes (0: generate in this process).
        seed: base seed; demo ``i`` of ``skill`` uses the stream (seed, skill, i).
        settle_steps: zero-action steps before the demonstration starts.
        idle_steps: zero-action steps after it (the final dough is taken after them).
        n_particles: simulated particles.
        obs_points: observed points ``P``.
        scene: ``"default"`` or a scene variant of the skill (:attr:`pasta.core.Skill.demo_variants`,
            e.g. push's ``"wide"``), usually added to a dataset with a larger ``num``
            (``num=350 scene=wide``: demos 200-349 in that variant).
        threads: the simulator's CPU threads in each worker (Taichi's ``cpu_max_num_threads``; the
            simulator is what computes here); 0: the simulator's default (:attr:`pasta.sim.SimConfig.cpu_threads`).
        expert: ``scripted`` (the skill's expert) or ``trajopt`` (GBTO toward the skill's ``demo_target``);
            empty: the scripted expert where the skill has one, else GBTO.
        trajopt_iterations: GBTO's Adam iterations per demonstration (each a rollout and its backward pass, ~0.2 s
            per env step at 5,000 particles on 2 cores); 0: the skill's own (:func:`pasta.tasks.step.gbto_budget`:
            its plugin's ``training_defaults``, else 20). Its other settings are Traj-Opt's defaults
            (:class:`pasta.config.run.TrajOptConfig`).
        trajopt_steps: the env steps of a GBTO demonstration; 0: the skill's own (else 50, the paper's).
    """

    skill: str = ""
    num: int = 200
    out: str = "data/demos"
    workers: int = 2
    seed: int = 0
    settle_steps: int = 10
    idle_steps: int = 10
    n_particles: int = 5000
    obs_points: int = 1000
    scene: str = "default"
    threads: int = 0
    expert: str = ""
    trajopt_iterations: int = 0
    trajopt_steps: int = 0


def demo_path(out: str | Path, skill: str, index: int) -> Path:
    return Path(out) / skill / f"demo_{index:05d}.npz"


def validate(cfg: DemoConfig) -> Path:
    """Check every argument before any work starts (nothing is created or written); returns the skill folder
    ``out/<skill>`` (created by :func:`generate_demos`)."""
    from pasta.config.validate import check_int, check_output_dir, check_seed, check_threads

    if not cfg.skill:
        raise ConfigError(f"`pasta demos` needs skill=NAME; skills with demonstrations: {', '.join(demo_skills()) or 'none'}")
    cls = check_demo_skill(cfg.skill)
    check_int(cfg.num, "num", low=1, high=MAX_DEMOS)
    check_int(cfg.workers, "workers", low=0, high=MAX_WORKERS)
    check_seed(cfg.seed, "seed")
    for name in ("settle_steps", "idle_steps"):
        check_int(getattr(cfg, name), name, low=0, high=MAX_IDLE)
    check_variant(cls, cfg.scene)
    check_threads(cfg.threads, "threads")
    expert_kind(cfg, cls)
    check_int(cfg.trajopt_iterations, "trajopt_iterations", low=0, high=100_000)
    check_int(cfg.trajopt_steps, "trajopt_steps", low=0, high=MAX_IDLE)
    sim_config(cfg)  # the simulator's own checks (n_particles, obs_points), before any simulator starts
    check_output_dir(cfg.out, "out")
    folder = Path(cfg.out).expanduser() / cfg.skill
    if folder.exists() and not folder.is_dir():
        raise ConfigError(f"out={cfg.out}: {folder} exists and is not a directory; give another out=")
    if folder.is_dir() and not os.access(folder, os.W_OK | os.X_OK):
        raise ConfigError(f"out={cfg.out}: cannot write demonstrations to {folder} (not writable)")
    return folder


#: how demonstrations are made (``expert=``): the skill's scripted expert, or GBTO toward its ``demo_target``
EXPERTS = ("scripted", "trajopt")


def expert_kind(cfg: DemoConfig, cls: type[Skill]) -> str:
    """``cfg.expert`` resolved for skill class ``cls`` (empty: ``scripted`` where the skill has an expert, else
    ``trajopt``). Raises ConfigError for an unknown kind or one the skill's hooks cannot make."""
    from pasta.config.validate import check_choice

    kind = str(cfg.expert) or ("scripted" if cls.has_expert() else "trajopt")
    check_choice(kind, "expert", EXPERTS)
    if kind == "scripted" and not cls.has_expert():
        raise ConfigError(f"expert=scripted: skill '{cfg.skill}' has no scripted expert (its plugin does not define "
                          f"{', '.join(cls.missing_demo_hooks())}); expert=trajopt makes its demonstrations from "
                          "demo_target")
    if kind == "trajopt" and not cls.has_gbto():
        raise ConfigError(f"expert=trajopt: skill '{cfg.skill}' defines no {', '.join(cls.missing_gbto_hooks())}, "
                          "the target trajectory optimisation needs")
    return kind


def sim_config(cfg: DemoConfig) -> Any:
    """The simulator settings demonstrations are made with (:class:`pasta.sim.SimConfig`)."""
    from pasta.sim import SimConfig

    try:
        return SimConfig(n_particles=cfg.n_particles, obs_points=cfg.obs_points,
                         max_particles=max(10000, cfg.n_particles),
                         cpu_threads=int(cfg.threads) or SimConfig.cpu_threads)  # threads=0: the simulator's default
    except (TypeError, ValueError) as exc:
        raise ConfigError(str(exc).removeprefix("sim.")) from None


def versions() -> dict[str, str]:
    out = {"python": platform.python_version()}
    for dist in ("pasta-dough", "numpy", "taichi", "scikit-learn"):
        try:
            out[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            out[dist] = "not installed"
    return out


def write_manifest(cfg: DemoConfig) -> Path:
    """Create or update ``out/manifest.json``: this skill's config, counts and versions."""
    from pasta.plugins import get_plugins

    root = Path(cfg.out)
    path = root / "manifest.json"
    manifest: dict[str, Any] = {}
    if path.exists():
        try:
            manifest = json.loads(path.read_text())
        except (OSError, json.JSONDecodeError):
            manifest = {}
    manifest["format"] = FORMAT
    manifest["versions"] = versions()
    skills = manifest.setdefault("skills", {})
    plugins = get_plugins()
    info = plugins.skills.info(cfg.skill)
    files = sorted((root / cfg.skill).glob("demo_*.npz"))
    skills[cfg.skill] = {
        "count": len(files),
        "tool": info.spec.tool,
        "config": asdict(cfg),
        "skill_config": _as_dict(skill_config(cfg.skill, cfg.scene)),
        "updated": time.strftime("%Y-%m-%dT%H:%M:%S"),
    }
    manifest["counts"] = {k: v["count"] for k, v in skills.items()}
    write_json(path, manifest, indent=1, sort_keys=True)
    return path


def _as_dict(obj: Any) -> dict:
    return asdict(obj) if obj is not None else {}


def skill_config(skill: str, scene: str = "default") -> Any:
    """The config the expert of ``skill`` runs with in scene variant ``scene`` (the default config with
    the variant's fields, :attr:`pasta.core.DemoVariant.config`)."""
    from pasta.plugins import get_plugins

    plugins = get_plugins()
    return variant_config(plugins.skills.default_config(skill), plugins.skills.load(skill), scene)


class DemoWriter:
    """Generates demonstrations of one skill in one process (one simulator, reused)."""

    def __init__(self, cfg: DemoConfig) -> None:
        from pasta.plugins import get_plugins
        from pasta.sim import Simulator

        self.cfg = cfg
        self.skill = get_plugins().skills.create(cfg.skill, skill_config(cfg.skill, cfg.scene))
        self.expert = expert_kind(cfg, type(self.skill))
        self.variant_record = variant_record(type(self.skill), cfg.scene)
        self.sim = Simulator(sim_config(cfg), tools=get_plugins().simulated_tools())

    def generate(self, index: int) -> dict[str, np.ndarray]:
        """The arrays of demonstration ``index`` (see the module docstring)."""
        from pasta.tasks.step import gbto_expert, run_skill

        cfg, sim, skill = self.cfg, self.sim, self.skill
        rng = np.random.default_rng([cfg.seed, zlib.crc32(cfg.skill.encode()), index])
        boxes = scene_boxes(skill, rng, sim.floor_y, cfg.scene)
        sim.reset(scene_particles(boxes, cfg.n_particles, rng)[0], seed=int(rng.integers(2**31)))
        for name, pose in demo_tools(skill, cfg.scene).items():
            sim.set_tool_pose(name, pose.position, yaw=pose.yaw)
        for _ in range(cfg.settle_steps):
            sim.step()
        obs = sim.observe()
        if self.expert == "trajopt":
            iterations, steps = gbto_settings(cfg, skill)
            params, approach, controller = gbto_expert(sim, skill, obs.dough, np.arange(len(obs.dough)), rng,
                                                       iterations=iterations, steps=steps, variant=cfg.scene)
            steps = len(controller.actions)
        else:
            params = {k: float(v) for k, v in skill.sample_expert_params(obs.dough, rng).items()}
            approach = skill.expert_approach_pose(obs.dough, params, scene=obs.dough)
            controller, steps = skill.expert(params), None
        run = run_skill(sim, skill, controller, np.arange(len(obs.dough)), None, approach=approach,
                        idle_steps=cfg.idle_steps, park=False, record=True, max_steps=steps)
        traj = run.trajectory
        assert traj is not None  # record=True
        arrays = traj.arrays(action_dim=len(traj.action[0]) if traj.action else 1)
        arrays["skill"] = np.array(cfg.skill)
        arrays["params"] = np.array(json.dumps({**params, "done": run.done, **_scene_record(boxes), **self.variant_record},
                                               sort_keys=True))
        arrays["final_dough"] = sim.observe().dough.astype(np.float32)
        arrays["dough_index"] = obs.dough_index.astype(np.int64)
        check_changed(skill, obs.dough, arrays["final_dough"], index)
        return arrays

    def write(self, index: int) -> tuple[int, float]:
        from pasta.tasks.npz import write_npz

        t0 = time.perf_counter()
        arrays = self.generate(index)
        write_npz(demo_path(self.cfg.out, self.cfg.skill, index), arrays)
        return int(arrays["action"].shape[0]), time.perf_counter() - t0


def check_changed(skill: Any, before: np.ndarray, after: np.ndarray, index: int, points: int = 500) -> float | None:
    """For a skill that turns one piece into one (``n_in == n_out == 1``: its demo scene is that piece), the
    Chamfer distance (m^2) between the dough before and after a demonstration; raises :class:`InputError` when
    it is below the distance at which pasta takes a piece for its goal (the skill's ``at_goal``, else
    ``perception.unchanged_threshold``) and the skill does not call the piece unfinished (:meth:`~pasta.core.Skill.unfinished`):
    such a step would never be planned or run, so its demonstrations would teach nothing. A skill that changes the number of pieces changes the scene whatever the distance (None)."""
    if skill.n_in != 1 or skill.n_out != 1:
        return None
    from pasta.core.errors import InputError
    from pasta.core.matching import UNCHANGED_THRESHOLD
    from pasta.core.metrics import chamfer, sample_points

    limit = float(skill.at_goal if getattr(skill, "at_goal", None) is not None else UNCHANGED_THRESHOLD)
    rng = np.random.default_rng(index)  # its own stream: the demonstration's draws are unchanged
    moved = float(chamfer(sample_points(before, points, rng), sample_points(after, points, rng)))
    if moved < limit and not skill.unfinished(before, after):
        source = "its at_goal" if getattr(skill, "at_goal", None) is not None else "perception.unchanged_threshold"
        raise InputError(f"skill '{skill.name}' demo {index}: its expert changed the dough by a Chamfer distance of "
                         f"{moved:.2e} m^2, below {limit:g} ({source}), the distance at which pasta takes a piece for "
                         "its goal: such a step is never planned or run. Make the expert's effect larger (its "
                         "parameters or its demo_scene)")
    return moved


def variant_record(cls: type[Skill], variant: str) -> dict[str, Any]:
    """What a demonstration's ``params`` say of its scene variant: nothing for ``default``; ``variant`` and,
    for a variant kept for some training stages only (:attr:`pasta.core.DemoVariant.stages`), ``stages``."""
    if variant == DEFAULT:
        return {}
    stages = list(cls.demo_variants[variant].stages)
    unknown = sorted(set(stages) - set(TRAINING_STAGES))
    if unknown:
        raise ConfigError(f"skill '{cls.spec.name}' scene variant '{variant}' names unknown training stages {unknown}; "
                          f"known: {', '.join(TRAINING_STAGES)}")
    return {"variant": variant, **({"stages": stages} if stages else {})}


def _scene_record(boxes: list[tuple]) -> dict[str, Any]:
    """The scene in a demo's ``params``: ``"scene": {centre, size}`` for one box (the format of the first
    datasets), ``"scenes": [{centre, size}, ...]`` for more."""
    rows = [{"centre": [float(v) for v in c], "size": [float(v) for v in s]} for c, s in boxes]
    return {"scene": rows[0]} if len(rows) == 1 else {"scenes": rows}


def pending(cfg: DemoConfig) -> list[int]:
    """Indices in ``[0, num)`` whose file does not exist yet (a symbolic link is not a demo: it is replaced)."""
    return [i for i in range(cfg.num) if not _is_regular(demo_path(cfg.out, cfg.skill, i))]


def _is_regular(path: Path) -> bool:
    return path.is_file() and not path.is_symlink()


def failure_report(cfg: DemoConfig, failures: dict[int, str]) -> str:
    """The error of a run that could not make every demo: each failed demo with its seed, and how to
    reproduce one in this process."""
    first = min(failures)
    rows = [f"  demo {i} (seed={cfg.seed} skill={cfg.skill} index={i}): {failures[i].splitlines()[0]}"
            for i in sorted(failures)[:10]]
    more = [f"  ... and {len(failures) - 10} more"] if len(failures) > 10 else []
    detail = failures[first].partition("\n")[2].rstrip()
    return "\n".join([f"{len(failures)} of {cfg.num} demos of {cfg.skill} could not be made "
                      f"(the others are written; rerun to retry, demos that exist are kept):", *rows, *more,
                      f"reproduce one in this process: pasta demos skill={cfg.skill} num={first + 1} seed={cfg.seed} "
                      f"out={cfg.out} workers=0 scene={cfg.scene}", *([detail] if detail else [])])


def demo_deadline(cfg: DemoConfig) -> float:
    """The default ``deadline_s`` of ``pasta demos``: a demo is at most ``settle_steps`` + the skill's
    ``max_steps`` + ``idle_steps`` simulator steps at ``n_particles``, sized by
    :func:`pasta.distributed.sized_deadline` (with the first demo's kernel compile; minutes, not seconds)."""
    from pasta.distributed import sized_deadline
    from pasta.plugins import get_plugins

    skill = get_plugins().skills.create(cfg.skill, skill_config(cfg.skill, cfg.scene))
    if expert_kind(cfg, type(skill)) == "trajopt":  # each iteration a rollout and its backward
        from pasta.sim.trajopt import GRADIENT_STEPS

        iterations, steps = gbto_settings(cfg, skill)
        limit = steps * (1 + GRADIENT_STEPS * iterations)
    else:
        limit = int(getattr(skill, "max_steps", 50))  # what run_skill stops the expert at
    return sized_deadline(cfg.settle_steps + limit + cfg.idle_steps, cfg.n_particles)


def gbto_settings(cfg: DemoConfig, skill: Any) -> tuple[int, int]:
    """``(iterations, steps)`` of a GBTO demonstration: ``trajopt_iterations`` / ``trajopt_steps``, each 0 meaning
    the skill's own (:func:`pasta.tasks.step.gbto_budget`)."""
    from pasta.tasks.step import gbto_budget

    iterations, steps = gbto_budget(skill)
    return cfg.trajopt_iterations or iterations, cfg.trajopt_steps or steps


def demo_init(setup: dict) -> DemoWriter:
    """A worker's state for demos (:func:`pasta.distributed.map_jobs`): one simulator, reused."""
    return DemoWriter(DemoConfig(**setup))


def demo_job(writer: DemoWriter, index: int, attempt: int) -> dict[str, np.ndarray]:
    """Demo ``index``'s arrays; the driver writes them (:func:`generate_demos`)."""
    return writer.generate(index)


def generate_demos(cfg: DemoConfig, *, progress: bool = True, max_attempts: int = MAX_ATTEMPTS,
                   backend: BackendConfig | None = None) -> dict[str, Any]:
    """Generate the missing demonstrations of ``cfg.skill`` and update the manifest.

    The demos are made by :func:`pasta.distributed.map_jobs`: in this process (``workers=0``), in
    ``cfg.workers`` local worker processes, or with ``backend`` Ray as Ray tasks (``cfg.workers``: the
    most in flight, 0: the cluster's CPUs). A demo whose worker dies, or is given up after
    ``backend.deadline_s`` seconds on it (0: :func:`demo_deadline`; not in this process), is retried, up
    to ``max_attempts`` times. Workers only compute; this process writes every file as its demo arrives,
    so an interrupted run loses only the demos in flight.

    Returns a summary: ``generated``, ``skipped``, ``wall_s``, ``mean_steps``, ``backend``.
    Raises :class:`ConfigError` on bad arguments before any work, :class:`DemoWorkerError` naming the
    demos (with their seeds) that could not be made, after the others are written.
    """
    backend = backend or BackendConfig()
    with OutputLock(validate(cfg), "out"):  # one process writes a skill's demo folder at a time
        return _generate(cfg, backend, progress=progress, max_attempts=max_attempts)


def _generate(cfg: DemoConfig, backend: BackendConfig, *, progress: bool, max_attempts: int) -> dict[str, Any]:
    from pasta.distributed import map_jobs
    from pasta.tasks.npz import write_npz

    (Path(cfg.out).expanduser() / cfg.skill).mkdir(parents=True, exist_ok=True)  # checked by validate()
    todo = pending(cfg)
    skipped = cfg.num - len(todo)
    write_manifest(cfg)
    t0 = time.perf_counter()
    steps: list[int] = []
    failures: dict[int, str] = {}
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

    from pasta.core.progress import on_terminal

    columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(), TimeRemainingColumn())
    workers = cfg.workers if backend.name == "ray" or len(todo) > 1 else 0
    try:  # the bar on stderr, a terminal only: stdout keeps the command's result line
        with Progress(*columns, console=Console(stderr=True), disable=not (todo and on_terminal(progress))) as bar:
            task = bar.add_task(f"demos {cfg.skill}", total=len(todo))
            for outcome in map_jobs(demo_init, demo_job, asdict(cfg), todo, backend=backend, workers=workers,
                                    max_attempts=max_attempts, deadline_s=backend.deadline_s or demo_deadline(cfg),
                                    label="demo", prog="pasta demos"):
                if outcome.error is None:
                    write_npz(demo_path(cfg.out, cfg.skill, outcome.item), outcome.value)
                    steps.append(int(outcome.value["action"].shape[0]))
                else:
                    failures[outcome.item] = outcome.error
                bar.advance(task)
    except BackendError as exc:
        raise DemoWorkerError(str(exc)) from None
    finally:
        write_manifest(cfg)
    if failures:
        raise DemoWorkerError(failure_report(cfg, failures))
    return {"generated": len(steps), "skipped": skipped, "wall_s": time.perf_counter() - t0,
            "mean_steps": float(np.mean(steps)) if steps else 0.0, "backend": backend.describe()}


def demo_tools(skill: Any, variant: str) -> dict:
    """``skill.demo_tools(variant)``; a plugin written before the hook took the variant is called without it."""
    import inspect

    try:
        takes_variant = len(inspect.signature(skill.demo_tools).parameters) >= 1
    except (TypeError, ValueError):
        takes_variant = True
    return skill.demo_tools(variant) if takes_variant else skill.demo_tools()
