"""Tasks: data plus a seeded generator of (initial state, goal) pairs with a ground-truth skill chain.

A :class:`Task` builds an initial scene (dough pieces as uniformly sampled particles), lets it settle,
then RUNS a chain of scripted experts with random parameters in the simulator; the final state is the
goal, so every goal is reachable. The chain is kept as the ground truth (:class:`GroundTruthStep`:
skill, the attended piece, expert parameters, the produced pieces and the state after the step) for
the oracle and for analysis. Instances are cached as ``.npz`` files (no pickle) under
``$PASTA_TASK_CACHE`` or ``~/.cache/pasta/tasks``, keyed by task, seed and a hash of every setting that
changes the result, so fixed test sets are generated once and reproduce byte for byte.

Pieces are sets of indices into the observed cloud (the simulator observes a fixed particle subset):
that is how a controller tracks the piece it acts on, and how a sub-goal is cut out of a recorded state.
"""

from __future__ import annotations

import hashlib
import json
import os
import zlib
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from pasta.core import InputError, PluginConfig, SimulationError, Skill, TaskScore
from pasta.core import Task as TaskInterface
from pasta.core.metrics import emd, normalized_improvement
from pasta.tasks.npz import read_npz, write_npz
from pasta.tasks.scene import standing_tool

#: bump when generated instances change for the same seed and settings (invalidates caches)
GENERATOR_VERSION = 1
#: task settings that only change the scoring, not the generated instances (left out of the cache key)
SCORING_FIELDS = ("threshold", "emd_points", "emd_seed")
#: the fixed test sets use these seeds (demonstrations and training scenes use other streams)
TEST_SEED_BASE = 1000
#: the validation sets (choose settings here, report on the test seeds) use these
VAL_SEED_BASE = 2000


def cache_root() -> Path:
    """Folder of cached task instances: ``$PASTA_TASK_CACHE`` or ``~/.cache/pasta/tasks``."""
    return Path(os.environ.get("PASTA_TASK_CACHE") or Path.home() / ".cache" / "pasta" / "tasks")


def fixed_test_seeds(num: int = 20) -> list[int]:
    """The seeds of a task's fixed test set of ``num`` instances."""
    if num < 1:
        raise InputError(f"num must be >= 1, got {num}")
    return list(range(TEST_SEED_BASE, TEST_SEED_BASE + num))


def fixed_val_seeds(num: int = 20) -> list[int]:
    """The seeds of a task's validation set of ``num`` instances (disjoint from the test seeds)."""
    if num < 1:
        raise InputError(f"num must be >= 1, got {num}")
    return list(range(VAL_SEED_BASE, VAL_SEED_BASE + num))


@dataclass
class TaskConfig(PluginConfig):
    """Settings shared by every task (subclassed per task; ``task.<key>=`` on the command line, ``name`` is the
    chosen task's).

    Attributes:
        threshold: success when the normalised improvement exceeds this (strictly).
        n_particles: simulated particles of the whole scene (split between pieces by volume).
        settle_steps: zero-action env steps before the initial state is taken.
        idle_steps: zero-action env steps after each skill step.
        emd_points: points sampled (same indices in both clouds) for the EMD metric.
        emd_seed: seed of that sample.
        max_retries: generation retries with a derived seed when the simulator diverges.
    """

    threshold: float = 0.8
    n_particles: int = 5000
    settle_steps: int = 10
    idle_steps: int = 10
    emd_points: int = 500
    emd_seed: int = 0
    max_retries: int = 3


@dataclass
class GroundTruthStep:
    """One step of a task's ground-truth chain.

    Attributes:
        skill: skill name.
        params: the expert's parameters.
        inputs: ``(K,)`` observed-point indices of the attended piece before the step.
        outputs: the produced pieces, one ``(K_i,)`` index array each (``n_out`` of them).
        state: ``(N, 3)`` float32 every particle after the step (the recorded intermediate goal).
        steps: env steps the expert took.
    """

    skill: str
    params: dict[str, Any]
    inputs: np.ndarray
    outputs: list[np.ndarray]
    state: np.ndarray
    steps: int = 0


@dataclass
class TaskInstance:
    """One generated (initial state, goal) pair with its ground truth.

    Attributes:
        task, seed, key: task name, generator seed, cache key (config hash).
        init: the initial simulator state (``pasta.sim.SimState``) after settling.
        goal_state: ``(N, 3)`` float32 every particle of the goal.
        steps: the ground-truth chain.
        pieces: observed-point index arrays of the initial pieces.
        meta: JSON-able facts (scene geometry, config, versions).
    """

    task: str
    seed: int
    key: str
    init: Any
    goal_state: np.ndarray
    steps: list[GroundTruthStep]
    pieces: list[np.ndarray]
    meta: dict[str, Any] = field(default_factory=dict)

    @property
    def obs_index(self) -> np.ndarray:
        return np.asarray(self.init.obs_index)

    @property
    def init_points(self) -> np.ndarray:
        """``(P, 3)`` the observed initial dough."""
        return np.asarray(self.init.x)[self.obs_index]

    @property
    def goal(self) -> np.ndarray:
        """``(P, 3)`` the observed goal cloud (same particles as the observation)."""
        return self.goal_state[self.obs_index]

    @property
    def skeleton(self) -> list[str]:
        return [s.skill for s in self.steps]

    def step_goal(self, h: int) -> np.ndarray:
        """``(G, 3)`` observed points of the pieces step ``h`` produces, in the recorded state after it."""
        step = self.steps[h]
        obs = step.state[self.obs_index]
        return obs[np.concatenate(step.outputs)]

    # -- serialisation ---------------------------------------------------------------------
    def to_arrays(self) -> dict[str, np.ndarray]:
        init = self.init
        arrays: dict[str, np.ndarray] = {
            "init_x": init.x, "init_v": init.v, "init_F": init.F, "init_C": init.C,
            "init_tools": init.tools, "obs_index": init.obs_index, "goal_state": self.goal_state,
            # rows of init_tools by name: the instance loads into a simulator with more (or other) tools
            "init_tool_names": np.array(list(init.tool_names), dtype=str),
        }
        for i, p in enumerate(self.pieces):
            arrays[f"piece_{i}"] = np.asarray(p, np.int64)
        chain = []
        for h, s in enumerate(self.steps):
            arrays[f"step{h}_state"] = np.asarray(s.state, np.float32)
            arrays[f"step{h}_inputs"] = np.asarray(s.inputs, np.int64)
            for j, o in enumerate(s.outputs):
                arrays[f"step{h}_out{j}"] = np.asarray(o, np.int64)
            chain.append({"skill": s.skill, "params": s.params, "num_outputs": len(s.outputs), "steps": s.steps})
        header = {"task": self.task, "seed": self.seed, "key": self.key, "num_pieces": len(self.pieces),
                  "chain": chain, "meta": self.meta, "init_step": int(init.step)}
        arrays["header"] = np.array(json.dumps(header, sort_keys=True))
        return arrays

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray]) -> TaskInstance:
        from pasta.sim import SimState

        header = json.loads(str(arrays["header"]))
        init = SimState(
            x=arrays["init_x"].astype(np.float32), v=arrays["init_v"].astype(np.float32),
            F=arrays["init_F"].astype(np.float32), C=arrays["init_C"].astype(np.float32),
            tools=arrays["init_tools"].astype(np.float64), obs_index=arrays["obs_index"].astype(np.int64),
            step=int(header["init_step"]),
            tool_names=tuple(str(t) for t in arrays["init_tool_names"]) if "init_tool_names" in arrays else (),
        )
        steps = []
        for h, c in enumerate(header["chain"]):
            steps.append(GroundTruthStep(
                skill=c["skill"], params=c["params"], inputs=arrays[f"step{h}_inputs"],
                outputs=[arrays[f"step{h}_out{j}"] for j in range(c["num_outputs"])],
                state=arrays[f"step{h}_state"], steps=int(c["steps"]),
            ))
        pieces = [arrays[f"piece_{i}"] for i in range(header["num_pieces"])]
        return cls(header["task"], int(header["seed"]), header["key"], init, arrays["goal_state"], steps, pieces, header["meta"])

    def save(self, path: str | Path) -> Path:
        return write_npz(path, self.to_arrays())

    @classmethod
    def load(cls, path: str | Path) -> TaskInstance:
        return cls.from_arrays(read_npz(path))


#: EMD to the goal before and after, the normalised improvement and success (:class:`pasta.core.TaskScore`)
Score = TaskScore


class Task(TaskInterface):
    """Base of the simulator tasks (implements :class:`pasta.core.Task`). Subclasses set :attr:`name`,
    :attr:`skeleton` and implement :meth:`build`, which runs scripted experts to make the goal.

    Args:
        config: the task's config dataclass (defaults when ``None``).
        sim_config: a :class:`pasta.sim.SimConfig` (defaults when ``None``; its ``n_particles`` is the task's).
        skill_configs: ``{skill name: its config}`` for the skills the task builds (``skill.<name>.*`` of the
            run config); a skill not named gets its registered defaults.
    """

    config_class: ClassVar[type] = TaskConfig
    #: config fields that only change the scoring (left out of the cache key); a task whose
    #: :meth:`score` reads settings of its own adds them
    scoring_fields: ClassVar[tuple[str, ...]] = SCORING_FIELDS

    def __init__(self, config: Any = None, sim_config: Any = None, *, skill_configs: Any = None) -> None:
        from dataclasses import replace

        from pasta.sim import SimConfig

        self.config = config if config is not None else self.config_class()
        self.sim_config = (SimConfig(n_particles=self.config.n_particles) if sim_config is None
                           else replace(sim_config, n_particles=self.config.n_particles))
        self.skill_configs = dict(skill_configs or {})
        self._skills: dict[str, Skill] = {}

    # -- pieces of the machinery ---------------------------------------------------------------
    @property
    def threshold(self) -> float:
        return float(self.config.threshold)

    def skill(self, name: str) -> Skill:
        """The registered skill ``name`` with its config (``skill_configs``, else its registered defaults),
        built once per task object."""
        if name not in self._skills:
            from pasta.plugins import get_plugins

            self._skills[name] = get_plugins().skills.create(name, self.skill_configs.get(name))
        return self._skills[name]

    def make_sim(self) -> Any:
        """A simulator of :attr:`sim_config` with every registered tool that has geometry."""
        from pasta.plugins import get_plugins
        from pasta.sim import Simulator

        return Simulator(self.sim_config, tools=get_plugins().simulated_tools())

    def key(self) -> str:
        """Hash of everything that changes a generated instance besides the seed."""
        from pasta.plugins import get_plugins

        plugins = get_plugins()
        skills, tools = {}, {}
        for name in sorted(set(self.skeleton)):
            info = plugins.skills.info(name)
            skill = self.skill(name)
            cfg = asdict(skill.config) if skill.config is not None else {}
            # settings only the heuristic controllers read do not change generated instances
            cfg = {k: v for k, v in cfg.items() if k not in getattr(skill, "heuristic_fields", ())}
            skills[name] = {"version": info.version, "config": cfg}
            # the geometry, actions and friction of the tools the chain uses (its own and the static ones
            # its scenes stand up) shape the goals too
            for tool in (skill.tool, *skill.demo_tools()):
                tools[tool] = repr(plugins.tools.info(tool).spec)
        config = {k: v for k, v in asdict(self.config).items() if k not in (*self.scoring_fields, "name")}
        # an instance's states name every tool of the simulator that made it (parked where unused), and a
        # simulator refuses a state naming a tool it lacks: an instance cached while a plugin's tool was
        # installed must not be read after it is gone
        simulated = [spec.name for spec in plugins.simulated_tools()]
        blob = json.dumps({"task": self.name, "config": config, "sim": asdict(self.sim_config), "skills": skills,
                           "tools": tools, "simulated_tools": simulated, "generator": GENERATOR_VERSION},
                          sort_keys=True, default=str)
        return hashlib.sha1(blob.encode()).hexdigest()[:12]

    def rng(self, seed: int, attempt: int = 0) -> np.random.Generator:
        return np.random.default_rng([int(seed), zlib.crc32(self.name.encode()), attempt])

    # -- generation ----------------------------------------------------------------------------
    def build(self, gen: Generation) -> None:
        """Create the scene and run the expert chain on ``gen`` (subclasses)."""
        raise NotImplementedError

    def generate(self, seed: int, sim: Any = None) -> TaskInstance:
        """Generate the instance of ``seed`` by running the expert chain (no cache)."""
        from pasta.sim import SimulationDiverged

        sim = sim if sim is not None else self.make_sim()
        last: Exception | None = None
        fallback: TaskInstance | None = None
        for attempt in range(self.config.max_retries + 1):
            gen = Generation(self, sim, self.rng(seed, attempt))
            try:
                self.build(gen)
            except SimulationDiverged as exc:
                last = exc
                continue
            inst = gen.instance(seed, attempt)
            if not gen.problems:
                return inst
            # a goal the task's own checks reject (an expert step that missed its target or disturbed
            # other pieces): draw new parameters; the last such goal is kept if every attempt fails
            inst.meta["problems"] = list(gen.problems)
            fallback = inst
        if fallback is not None:
            return fallback
        raise SimulationError(f"task '{self.name}' seed {seed}: every generation attempt diverged: {last}")

    def cache_path(self, seed: int) -> Path:
        return cache_root() / self.name / f"seed{seed:05d}-{self.key()}.npz"

    def instance(self, seed: int, *, sim: Any = None, cache: bool = True) -> TaskInstance:
        """The instance of ``seed``, from the cache when there (generated and cached otherwise)."""
        path = self.cache_path(seed)
        if cache and path.exists():
            return TaskInstance.load(path)
        inst = self.generate(seed, sim)
        if cache:
            inst.save(path)
        return inst

    def test_set(self, num: int = 20, *, sim: Any = None, cache: bool = True, progress: Any = None) -> list[TaskInstance]:
        """The fixed test set: instances of :func:`fixed_test_seeds` ``(num)``."""
        out = []
        for seed in fixed_test_seeds(num):
            if sim is None and not (cache and self.cache_path(seed).exists()):
                sim = self.make_sim()
            out.append(self.instance(seed, sim=sim, cache=cache))
            if progress is not None:
                progress()
        return out

    # -- scoring -------------------------------------------------------------------------------
    def score(self, final_points: np.ndarray, instance: TaskInstance) -> Score:
        """Score the observed final dough ``(P, 3)`` against the instance's observed goal."""
        cfg = self.config
        goal = instance.goal
        e0 = emd(instance.init_points, goal, n=cfg.emd_points, seed=cfg.emd_seed)
        e1 = emd(np.asarray(final_points), goal, n=cfg.emd_points, seed=cfg.emd_seed)
        ni = normalized_improvement(e0, e1)
        return Score(e0, e1, ni, ni > self.threshold)


class Generation:
    """Bookkeeping while a task builds one instance: the simulator, the rng, pieces and the chain."""

    def __init__(self, task: Task, sim: Any, rng: np.random.Generator) -> None:
        self.task, self.sim, self.rng = task, sim, rng
        self.pieces: list[np.ndarray] = []
        self.steps: list[GroundTruthStep] = []
        self.meta: dict[str, Any] = {}
        self.init: Any = None
        self.init_pieces: list[np.ndarray] = []
        #: reasons the task's checks reject this goal (:meth:`check_push`); a rejected goal is redrawn
        self.problems: list[str] = []

    def start(self, boxes: list[tuple[tuple[float, float, float], tuple[float, float, float]]]) -> list[np.ndarray]:
        """Load a scene of boxes ``[(centre, size), ...]`` (particles split by volume), settle it, stand
        the task's static tools (:attr:`Task.static_tools`) at their stand poses, take the initial state
        and return the pieces (observed-point indices, one array per box)."""
        from pasta.sim import box_particles

        cfg = self.task.config
        vols = np.array([np.prod(s) for _, s in boxes], np.float64)
        counts = np.floor(cfg.n_particles * vols / vols.sum()).astype(int)
        counts[0] += cfg.n_particles - counts.sum()
        parts, owner = [], []
        for i, ((c, s), n) in enumerate(zip(boxes, counts)):
            parts.append(box_particles(c, s, int(n), self.rng))
            owner.append(np.full(int(n), i))
        particles, owner_all = np.concatenate(parts), np.concatenate(owner)
        self.sim.reset(particles, seed=int(self.rng.integers(2**31)))
        for _ in range(cfg.settle_steps):
            self.sim.step()
        for tool in self.task.static_tools:  # after settling: the dough settles on the floor, beside them
            self.sim.set_tool_pose(tool, tuple(float(v) for v in standing_tool(tool).stand))
        self.init = self.sim.get_state()
        obs_owner = owner_all[self.init.obs_index]
        self.pieces = [np.flatnonzero(obs_owner == i) for i in range(len(boxes))]
        self.init_pieces = [p.copy() for p in self.pieces]
        self.meta["boxes"] = [{"centre": [float(v) for v in c], "size": [float(v) for v in s]} for c, s in boxes]
        return self.pieces

    def observe(self) -> np.ndarray:
        return self.sim.observe().dough

    def run(self, skill_name: str, piece: int, params: dict[str, float] | None = None) -> list[int]:
        """Run the expert of ``skill_name`` on piece number ``piece`` (random parameters when None); a skill
        without a scripted expert but with ``demo_target`` gets its step by trajectory optimisation
        (:func:`pasta.tasks.step.gbto_expert`, its record as the step's params).

        The produced pieces replace the consumed one in :attr:`pieces` (cut: left part at ``piece``,
        right part inserted after it). Returns the indices of the produced pieces in :attr:`pieces`.
        """
        from pasta.tasks.step import gbto_expert, run_skill

        skill = self.task.skill(skill_name)
        idx = self.pieces[piece]
        dough = self.observe()
        limit = None
        controller: Any
        if type(skill).goals_by_trajopt():
            record, approach, controller = gbto_expert(self.sim, skill, dough, idx, self.rng)
            params, limit = record, len(controller.actions)
        else:
            if params is None:
                params = skill.sample_expert_params(dough[idx], self.rng)
            params = {k: float(v) for k, v in params.items()}
            approach = skill.expert_approach_pose(dough[idx], params, scene=dough)
            controller = skill.expert(params)
        run = run_skill(self.sim, skill, controller, idx, None, approach=approach,
                        idle_steps=self.task.config.idle_steps, max_steps=limit)
        after = self.observe()
        outputs = split_pieces(after[idx], idx, skill.n_out)
        state = self.sim.particles().astype(np.float32)
        self.steps.append(GroundTruthStep(skill_name, params, idx.copy(), outputs, state, run.steps))
        self.pieces[piece:piece + 1] = outputs
        return list(range(piece, piece + len(outputs)))

    def check_push(self, piece: int, params: dict[str, float], before: np.ndarray, *, tolerance: float,
                   max_disturbance: float) -> None:
        """After a push of piece number ``piece`` with target ``params``: record a problem when its
        centroid (xz) ended more than ``tolerance`` from the target, or when another piece's centroid moved
        more than ``max_disturbance`` from where it was in ``before (P, 3)`` (the observed dough before
        the push)."""
        after = self.observe()
        c = after[self.pieces[piece]][:, [0, 2]].mean(0)
        miss = float(np.hypot(c[0] - params["target_x"], c[1] - params["target_z"]))
        if miss > tolerance:
            self.problems.append(f"step {len(self.steps) - 1}: push ended {miss:.3f} from its target")
        for j, other in enumerate(self.pieces):
            if j == piece:
                continue
            moved = float(np.linalg.norm(after[other].mean(0) - before[other].mean(0)))
            if moved > max_disturbance:
                self.problems.append(f"step {len(self.steps) - 1}: push moved piece {j} by {moved:.3f}")

    def instance(self, seed: int, attempt: int) -> TaskInstance:
        self.meta.update({"attempt": attempt, "generator_version": GENERATOR_VERSION,
                          "config": asdict(self.task.config)})
        goal = self.sim.particles().astype(np.float32)
        return TaskInstance(self.task.name, seed, self.task.key(), self.init, goal, self.steps,
                            self.init_pieces, self.meta)


def split_pieces(points: np.ndarray, idx: np.ndarray, n_out: int) -> list[np.ndarray]:
    """Split the piece ``idx`` (observed-point indices whose current positions are ``points (K, 3)``)
    into ``n_out`` produced pieces, ordered by centroid ``x``.

    One piece stays one. Two or more: DBSCAN (:func:`pasta.core.decompose.decompose_labels`); when it
    does not find ``n_out`` clusters, the widest ``x`` gaps split the piece (cuts are planes x = const).
    """
    if n_out == 1:
        return [np.asarray(idx, np.int64).copy()]
    from pasta.core.decompose import decompose_labels

    labels = decompose_labels(points, min_points=10)
    if int(labels.max()) + 1 != n_out:
        order = np.argsort(points[:, 0], kind="stable")
        xs = points[order, 0]
        lo = max(1, len(xs) // 20)
        gaps = xs[lo:len(xs) - lo + 1] - xs[lo - 1:len(xs) - lo]
        cuts = np.sort(np.argsort(gaps)[::-1][: n_out - 1] + lo)
        labels = np.empty(len(points), np.int64)
        for k, (a, b) in enumerate(zip(np.r_[0, cuts], np.r_[cuts, len(xs)])):
            labels[order[a:b]] = k
    out = [np.asarray(idx)[labels == k] for k in range(n_out)]
    return sorted(out, key=lambda o: float(points[np.isin(idx, o), 0].mean()))
