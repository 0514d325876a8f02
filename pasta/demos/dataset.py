"""Load a demonstration dataset (see :mod:`pasta.demos.generate` for the layout) and draw batches.

A sample is one step ``t`` of one demonstration: the observed dough ``dough[t] (P, 3)``, the tool
points ``tool_points[t] (Tp, 3)``, a goal cloud ``(P, 3)`` and the action ``action[t] (A,)``. The goal is
the demonstration's final dough (``final_dough``: after the idle steps) or, with probability
``hindsight_ratio``, a hindsight goal ``dough[t']`` for ``t'`` uniform in ``(t, T]``. ``done`` is 1 when
the goal is reached by the current action (``t' = t + 1``, or ``t = T - 1`` for the final goal).
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pasta.core.errors import InputError

KEYS = ("dough", "tool_points", "tool_pose", "action", "skill", "params")


@dataclass
class Demonstration:
    """One demonstration as stored (``np.ndarray``)."""

    skill: str
    dough: np.ndarray  # (T+1, P, 3)
    tool_points: np.ndarray  # (T+1, Tp, 3)
    tool_pose: np.ndarray  # (T+1, 7)
    action: np.ndarray  # (T, A)
    params: dict = field(default_factory=dict)
    final_dough: np.ndarray | None = None  # (P, 3)
    path: str = ""

    @property
    def steps(self) -> int:
        return int(self.action.shape[0])

    @property
    def goal(self) -> np.ndarray:
        """``(P, 3)``: the settled final dough when stored, else the dough after the last action."""
        return self.final_dough if self.final_dough is not None else self.dough[-1]


@dataclass
class DemoBatch:
    """``obs (B, P, 3)``, ``tool (B, Tp, 3)``, ``goal (B, P, 3)``, ``action (B, A)``, ``done (B,)``; float32."""

    obs: np.ndarray
    tool: np.ndarray
    goal: np.ndarray
    action: np.ndarray
    done: np.ndarray


def load_demo(path: str | Path) -> Demonstration:
    """Read one demo file (no pickle) and check its shapes."""
    with np.load(path, allow_pickle=False) as z:
        missing = [k for k in KEYS if k not in z.files]
        if missing:
            raise InputError(f"{path}: not a demonstration file (missing {', '.join(missing)})")
        demo = Demonstration(
            skill=str(z["skill"]), dough=z["dough"].astype(np.float32), tool_points=z["tool_points"].astype(np.float32),
            tool_pose=z["tool_pose"].astype(np.float32), action=z["action"].astype(np.float32),
            params=json.loads(str(z["params"])), final_dough=z["final_dough"].astype(np.float32) if "final_dough" in z.files else None,
            path=str(path),
        )
    t = demo.steps
    if demo.dough.ndim != 3 or demo.dough.shape[0] != t + 1 or demo.tool_points.shape[0] != t + 1 or demo.tool_pose.shape != (t + 1, 7):
        raise InputError(f"{path}: expected dough (T+1, P, 3), tool_points (T+1, Tp, 3), tool_pose (T+1, 7), action (T, A); "
                         f"got {demo.dough.shape}, {demo.tool_points.shape}, {demo.tool_pose.shape}, {demo.action.shape}")
    return demo


class DemoDataset:
    """All demonstrations under ``root`` (optionally only ``skills``), loaded into memory.

    Raises:
        InputError: the folder has no manifest or no demonstrations of a requested skill.
    """

    def __init__(self, root: str | Path, skills: list[str] | None = None) -> None:
        self.root = Path(root)
        manifest = self.root / "manifest.json"
        if not manifest.exists():
            raise InputError(f"{self.root} is not a demonstration dataset (no manifest.json); run `pasta demos` first")
        self.manifest = json.loads(manifest.read_text())
        names = skills if skills is not None else sorted(self.manifest.get("skills", {}))
        self.demos: dict[str, list[Demonstration]] = {}
        for name in names:
            files = sorted((self.root / name).glob("demo_*.npz"))
            if not files:
                raise InputError(f"no demonstrations of '{name}' in {self.root / name}")
            self.demos[name] = [load_demo(f) for f in files]

    @property
    def skills(self) -> list[str]:
        return list(self.demos)

    def __len__(self) -> int:
        return sum(len(v) for v in self.demos.values())

    def num_steps(self, skill: str) -> int:
        return sum(d.steps for d in self.demos[skill])

    def batches(self, skill: str, batch_size: int, *, seed: int = 0, hindsight_ratio: float = 0.5,
                num_batches: int | None = None) -> Iterator[DemoBatch]:
        """Random batches of ``skill`` steps (``num_batches`` of them, or one pass worth by default)."""
        if skill not in self.demos:
            raise InputError(f"dataset has no '{skill}' demonstrations; it has: {', '.join(self.demos)}")
        if batch_size < 1 or not 0.0 <= hindsight_ratio <= 1.0:
            raise InputError("batch_size must be >= 1 and hindsight_ratio in [0, 1]")
        demos = [d for d in self.demos[skill] if d.steps > 0]
        if not demos:
            raise InputError(f"every '{skill}' demonstration is empty")
        rng = np.random.default_rng(seed)
        steps = np.array([d.steps for d in demos])
        total = int(steps.sum())
        count = num_batches if num_batches is not None else max(1, total // batch_size)
        weights = steps / total
        for _ in range(count):
            which = rng.choice(len(demos), size=batch_size, p=weights)
            obs, tool, goal, action, done = [], [], [], [], []
            for k in which:
                d = demos[k]
                t = int(rng.integers(d.steps))
                if rng.random() < hindsight_ratio:
                    later = int(rng.integers(t + 1, d.steps + 1))
                    goal.append(d.dough[later])
                    done.append(float(later == t + 1))
                else:
                    goal.append(d.goal)
                    done.append(float(t == d.steps - 1))
                obs.append(d.dough[t])
                tool.append(d.tool_points[t])
                action.append(d.action[t])
            yield DemoBatch(np.stack(obs), np.stack(tool), np.stack(goal), np.stack(action).astype(np.float32),
                            np.asarray(done, np.float32))
