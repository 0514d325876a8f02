"""Every registered task as a Gymnasium environment: ``gymnasium.make("pasta/crs-v0")`` (docs/gymnasium.md).

Importing this module registers ``pasta/<task>-v0`` for every task the plugin registry knows, so a task
plugin gets an environment with no code of its own (``gymnasium.make("pasta.envs:pasta/crs-v0")`` imports it
on the way).

- **Observation** (a ``Dict`` of ``Box``es, fixed shapes): ``dough`` ``(points, 3)`` the observed dough,
  ``goal`` ``(points, 3)`` the goal (both in the unit-cube workspace, y up; the same particle subset for the
  whole episode), ``tools`` ``(T, 7)`` each tool's position and quaternion (w, x, y, z).
- **Action**: the paper's all-tools layout, one ``Box([-1, 1])`` of every channel of every tool of the task's
  skills, concatenated in the order of :attr:`TaskEnv.tools` (``TaskEnv.action_layout`` names them); the
  simulator scales each channel (``ToolSpec.action``). Tools start parked, as after a simulator reset.
- **Reward**: the decrease of the task's distance to the goal (the EMD the task scores with), over its initial
  value, so the rewards of an episode add up to its normalised improvement.
- **terminated**: the normalised improvement passed the task's success threshold (or the simulation
  diverged); **truncated**: the task's step budget (every skill of its chain at its ``max_steps``) is spent.
  ``info``: ``improvement``, ``success``, ``emd``, ``instance`` (the task instance's seed).
- **Seeding**: ``reset(seed=s)`` draws the instance and the observed particle subsets from ``s``: the same
  seed and actions give the same episode, bit for bit. Instances come from ``seeds`` (a pool; default 100
  training seeds from :data:`TRAIN_SEED_BASE`, apart from the test and validation sets), generated on first
  use and cached; ``options={"instance": S}`` picks one.
- ``render_mode="rgb_array"``: a top and a side view of the dough, the goal and the tools.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces

__all__ = ["TRAIN_SEED_BASE", "RayVectorEnv", "TaskEnv", "env_id", "register_envs"]

#: the task instances an environment draws by default: seeds from here on (the test sets start at 1000,
#: the validation sets at 2000)
TRAIN_SEED_BASE = 100_000
ENV_VERSION = 0


def env_id(task: str) -> str:
    """The Gymnasium id of a registered task: ``pasta/<task>-v0``."""
    return f"pasta/{task}-v{ENV_VERSION}"


def register_envs() -> list[str]:
    """Register ``pasta/<task>-v0`` for every registered task (again after a plugin is installed); the ids."""
    from pasta.plugins import get_plugins

    ids = []
    for name in get_plugins().tasks.names():
        ids.append(env_id(name))
        if ids[-1] not in gymnasium.registry:
            gymnasium.register(ids[-1], entry_point="pasta.envs:TaskEnv", kwargs={"task": name})
    return ids


class TaskEnv(gymnasium.Env):
    """A registered pasta task as a Gymnasium environment (see the module docstring for the spaces).

    Args:
        task: the registered task name.
        points: observed dough and goal points per observation.
        seeds: the task instances to draw from (default ``instances`` seeds from :data:`TRAIN_SEED_BASE`).
        instances: the size of the default pool.
        render_mode: ``None`` or ``"rgb_array"``.
        settings: the task's settings (``task.<key>`` of the run config), e.g. ``{"distractors": 4}``.
    """

    metadata: dict[str, Any] = {"render_modes": ["rgb_array"], "render_fps": 10}  # noqa: RUF012 - as gymnasium.Env declares it

    def __init__(self, task: str = "crs", *, points: int = 512, seeds: Sequence[int] | None = None,
                 instances: int = 100, render_mode: str | None = None, settings: dict[str, Any] | None = None) -> None:
        from pasta.config.validate import check_int
        from pasta.core.errors import ConfigError
        from pasta.tasks import get_task

        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ConfigError(f"render_mode={render_mode!r}: choose one of {self.metadata['render_modes']} or None")
        self.points = check_int(points, "points", low=16, high=100_000)
        self.task = get_task(task, **(settings or {}))
        self.seeds = tuple(int(s) for s in seeds) if seeds else tuple(range(TRAIN_SEED_BASE, TRAIN_SEED_BASE
                                                                         + check_int(instances, "instances", low=1)))
        self.render_mode = render_mode
        chain = [self.task.skill(name) for name in self.task.skeleton]  # built once per name by the task
        self.tools = tuple(dict.fromkeys(skill.tool for skill in chain))
        self.max_steps = int(sum(int(getattr(skill, "max_steps", 100)) for skill in chain))
        self._sim: Any = None
        self._specs: dict[str, Any] = {}
        self.action_layout: list[tuple[str, str]] = []  # (tool, channel) per action component
        from pasta.plugins import get_plugins

        for tool in self.tools:
            spec = get_plugins().tools.info(tool).spec
            self._specs[tool] = spec
            self.action_layout += [(tool, channel.kind) for channel in spec.action]
        self.observation_space = spaces.Dict({
            "dough": spaces.Box(0.0, 1.0, (self.points, 3), np.float32),
            "goal": spaces.Box(0.0, 1.0, (self.points, 3), np.float32),
            "tools": spaces.Box(-1.0, 1.0, (len(self.tools), 7), np.float32),
        })
        self.action_space = spaces.Box(-1.0, 1.0, (len(self.action_layout),), np.float32)
        self._instance: Any = None

    # -- Gymnasium API -------------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[dict, dict]:
        super().reset(seed=seed)
        options = options or {}
        chosen = options.get("instance")
        instance_seed = int(chosen) if chosen is not None else int(self.np_random.choice(self.seeds))
        self._instance = inst = self.task.instance(instance_seed)
        sim = self._simulator()
        sim.set_state(inst.init)
        seen = sim.observe()
        self._dough_idx = self._subset(len(seen.dough))
        self._goal = np.asarray(inst.goal, np.float32)[self._subset(len(inst.goal))]
        self._e0 = self._emd(seen.dough)
        self._emd_now, self._steps = self._e0, 0
        return self._observation(seen), self._info()

    def step(self, action: Any) -> tuple[dict, float, bool, bool, dict]:
        from pasta.sim import SimulationDiverged

        if self._instance is None:
            raise gymnasium.error.ResetNeeded("call reset() before step()")
        a = np.clip(np.asarray(action, np.float32).reshape(-1), -1.0, 1.0)
        if a.shape != self.action_space.shape:
            raise ValueError(f"action must have shape {self.action_space.shape} ({self.action_layout}), got {a.shape}")
        per_tool, k = {}, 0
        for tool in self.tools:
            n = len(self._specs[tool].action)
            per_tool[tool], k = a[k:k + n], k + n
        sim = self._simulator()
        self._steps += 1
        try:
            sim.step(per_tool)
        except SimulationDiverged as exc:  # the state is invalid: the episode ends, without reward
            sim.set_state(self._instance.init)
            return self._observation(sim.observe()), 0.0, True, False, {**self._info(), "diverged": str(exc)}
        seen = sim.observe()
        before, self._emd_now = self._emd_now, self._emd(seen.dough)
        reward = float((before - self._emd_now) / self._e0)
        info = self._info()
        return self._observation(seen), reward, bool(info["success"]), self._steps >= self.max_steps, info

    def render(self) -> np.ndarray | None:
        if self.render_mode != "rgb_array" or self._instance is None:
            return None
        return _render(self._simulator(), self._goal, title=f"{self.task.name}  step {self._steps}")

    def close(self) -> None:
        self._sim = None

    # -- pieces ----------------------------------------------------------------------------------------
    def _simulator(self) -> Any:
        if self._sim is None:  # started on first use: Taichi compiles its kernels once per process
            self._sim = self.task.make_sim()
        return self._sim

    def _subset(self, n: int) -> np.ndarray:
        return np.sort(self.np_random.choice(n, self.points, replace=n < self.points))

    def _emd(self, observed: np.ndarray) -> float:
        from pasta.core.metrics import emd

        cfg = self.task.config
        return float(emd(observed, self._instance.goal, n=cfg.emd_points, seed=cfg.emd_seed))

    def _observation(self, seen: Any) -> dict[str, np.ndarray]:
        """The Dict observation of one simulator observation (its dough subset, the goal, the tool poses)."""
        poses = seen.tool_poses
        tools = np.stack([np.asarray(poses[t], np.float32) for t in self.tools]) if self.tools else np.zeros((0, 7))
        return {"dough": np.clip(seen.dough[self._dough_idx], 0.0, 1.0).astype(np.float32),
                "goal": np.clip(self._goal, 0.0, 1.0).astype(np.float32),
                "tools": np.clip(tools, -1.0, 1.0).astype(np.float32)}

    def _info(self) -> dict[str, Any]:
        improvement = (self._e0 - self._emd_now) / self._e0 if self._e0 > 0 else 0.0
        return {"improvement": float(improvement), "success": bool(improvement > self.task.threshold),
                "emd": float(self._emd_now), "instance": int(self._instance.seed)}


class _EnvActor:
    """One :class:`TaskEnv` in a Ray worker process (the body of :class:`RayVectorEnv`'s actors)."""

    def __init__(self, task: str, kwargs: dict[str, Any], env: dict[str, str]) -> None:
        from pasta.distributed import apply_env

        apply_env(env)  # the driver's PASTA_* settings (cache folders)
        self.env = TaskEnv(task, **kwargs)

    def reset(self, seed: int | None, options: dict[str, Any] | None) -> tuple[dict, dict]:
        return self.env.reset(seed=seed, options=options)

    def step(self, action: np.ndarray) -> tuple[dict, float, bool, bool, dict]:
        return self.env.step(action)


class RayVectorEnv(gymnasium.vector.VectorEnv):
    """``num_envs`` copies of a task's environment, each a Ray actor (one CPU, its own simulator), stepped
    together: Gymnasium's vector API (batched spaces, ``info`` dicts with ``_key`` masks, the next-step
    autoreset of ``AsyncVectorEnv``), on a local Ray instance or a cluster (``address``: as ``ray.address``
    of docs/scaling.md). ``kwargs``: :class:`TaskEnv`'s (``points``, ``seeds``, ``settings``, ...).
    ``reset(seed=s)`` seeds environment ``i`` with ``s + i``."""

    metadata: dict[str, Any] = {"autoreset_mode": gymnasium.vector.AutoresetMode.NEXT_STEP}  # noqa: RUF012

    def __init__(self, task: str, num_envs: int, *, address: str = "", num_cpus: int = 0, **kwargs: Any) -> None:
        from gymnasium.vector.utils import batch_space

        from pasta.config.validate import check_int
        from pasta.distributed import BackendConfig, shipped_env
        from pasta.distributed.ray_backend import ensure_ray

        self.num_envs = check_int(num_envs, "num_envs", low=1)
        probe = TaskEnv(task, **kwargs)  # checks the arguments here, before any worker starts; no simulator yet
        self.single_observation_space, self.single_action_space = probe.observation_space, probe.action_space
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self._ray = ensure_ray(BackendConfig(name="ray", address=address, num_cpus=num_cpus))
        actor = self._ray.remote(num_cpus=1)(_EnvActor)
        self._actors = [actor.remote(task, kwargs, shipped_env()) for _ in range(self.num_envs)]
        self._done = np.zeros(self.num_envs, bool)

    def _batch(self, observations: list[dict]) -> dict:
        from gymnasium.vector.utils import concatenate, create_empty_array

        out: Any = create_empty_array(self.single_observation_space, self.num_envs)
        batched: dict = concatenate(self.single_observation_space, observations, out)  # type: ignore[assignment]
        return batched  # a Dict space batches to a dict

    def reset(self, *, seed: int | list[int | None] | None = None,
              options: dict[str, Any] | None = None) -> tuple[dict, dict]:
        seeds = [None if seed is None else int(seed) + i for i in range(self.num_envs)] if not isinstance(seed, list) \
            else seed
        results = self._ray.get([a.reset.remote(s, options) for a, s in zip(self._actors, seeds)])
        infos: dict[str, Any] = {}
        for i, (_, info) in enumerate(results):
            infos = self._add_info(infos, info, i)
        self._done[:] = False
        return self._batch([obs for obs, _ in results]), infos

    def step(self, actions: Any) -> tuple[dict, np.ndarray, np.ndarray, np.ndarray, dict]:
        actions = np.asarray(actions, np.float32).reshape(self.num_envs, -1)
        refs = [a.reset.remote(None, None) if self._done[i] else a.step.remote(actions[i])
                for i, a in enumerate(self._actors)]  # an environment that ended last step starts its next episode
        results = self._ray.get(refs)
        obs: list[dict] = []
        infos: dict[str, Any] = {}
        rewards, terminated, truncated = np.zeros(self.num_envs), np.zeros(self.num_envs, bool), np.zeros(self.num_envs, bool)
        for i, res in enumerate(results):
            if self._done[i]:
                o, info = res
            else:
                o, rewards[i], terminated[i], truncated[i], info = res
            obs.append(o)
            infos = self._add_info(infos, info, i)
        self._done = terminated | truncated
        return self._batch(obs), rewards, terminated, truncated, infos

    def close_extras(self, **kwargs: Any) -> None:
        for actor in getattr(self, "_actors", []):
            self._ray.kill(actor)
        self._actors = []


def _render(sim: Any, goal: np.ndarray, *, title: str = "", dpi: int = 80) -> np.ndarray:
    """``(H, W, 3)`` uint8: the top (x-z) and side (x-y) views of the dough (blue), the goal (grey) and the
    tools (their outlines, in their colours)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from pasta.execute.runlog import tool_primitives
    from pasta.io.views import draw_tools, view_box

    dough = sim.observe().dough
    box = view_box([dough, goal], up=1, side_ratio=0.35)
    fig = Figure(figsize=(6.4, 4.8), dpi=dpi)
    FigureCanvasAgg(fig)
    top, side = fig.subplots(2, 1)
    prims = tool_primitives(sim)
    for ax, (a, b) in ((top, (0, 2)), (side, (0, 1))):
        ax.scatter(goal[:, a], goal[:, b], s=2, c="#b0b0b0")
        ax.scatter(dough[:, a], dough[:, b], s=2, c="#1f3a64")
        draw_tools(ax, prims, (a, b), box=box)  # parked tools (outside the box) are left out
        ax.set_xlim(box[0][a], box[1][a])
        ax.set_ylim(box[0][b], box[1][b])
        ax.set_aspect("equal")
        ax.set_xlabel("xyz"[a], fontsize=8)
        ax.set_ylabel("xyz"[b], fontsize=8)
        ax.tick_params(labelsize=7)
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    canvas = fig.canvas
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[..., :3].copy()  # type: ignore[attr-defined]  # Agg canvas


register_envs()
