"""Reader of demonstration datasets, the split by demonstration, and per-step entity extraction.

Dataset format (written by ``pasta demos``)::

    DIR/manifest.json
    DIR/<skill>/demo_00000.npz     np.savez_compressed, loads with allow_pickle=False:
        dough        (T+1, P, 3) float32   observed dough cloud per step (the same particles each step)
        tool_points  (T+1, Tp, 3) float32
        tool_pose    (T+1, 7) float32
        action       (T, A) float32
        skill        0-d str
        params       0-d str (JSON)
        final_dough  (P, 3) float32   optional: the dough after the skill's idle steps (``pasta demos``)
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pasta.core.errors import InputError

DEMO_PATTERN = re.compile(r"^demo_(\d{5})\.npz$")
REQUIRED = {"dough": 3, "tool_points": 3, "tool_pose": 2, "action": 2}


@dataclass
class Demo:
    """One demonstration of one skill (arrays as stored, ``np.ndarray``)."""

    skill: str
    index: int
    dough: np.ndarray  # (T+1, P, 3)
    tool_points: np.ndarray  # (T+1, Tp, 3)
    tool_pose: np.ndarray  # (T+1, 7)
    action: np.ndarray  # (T, A)
    params: dict = field(default_factory=dict)
    path: str = ""
    final_dough: np.ndarray | None = None  # (P, 3) after the skill's idle steps, when the file has it

    @property
    def after(self) -> np.ndarray:
        """``(P, 3)`` the dough after the skill: ``final_dough`` if stored, else the last step."""
        return self.dough[-1] if self.final_dough is None else self.final_dough

    @property
    def key(self) -> str:
        """Unique id inside a dataset, ``"cut/00003"``."""
        return f"{self.skill}/{self.index:05d}"

    @property
    def num_steps(self) -> int:
        return len(self.action)


def read_manifest(data_dir: str | Path) -> dict:
    """The dataset's ``manifest.json`` as a dict.

    Raises:
        InputError: the directory or its manifest is missing or unreadable.
    """
    d = Path(data_dir)
    if not d.is_dir():
        raise InputError(f"dataset directory {d} does not exist: generate demonstrations with `pasta demos` first")
    path = d / "manifest.json"
    if not path.is_file():
        skills = sorted(p.name for p in d.iterdir() if p.is_dir() and any(p.glob("demo_*.npz")))
        fix = (f"`pasta demos skill={skills[0]} num=N out={d}` writes it (existing demo files are kept)" if skills
               else f"generate demonstrations into it with `pasta demos skill=NAME out={d}`")
        raise InputError(f"{d} is not a pasta dataset: no manifest.json; {fix}")
    try:
        return json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise InputError(f"{path} is not valid JSON: {exc}") from None


def demo_paths(data_dir: str | Path, skills: Iterable[str] | None = None) -> list[Path]:
    """Paths of the demonstrations under ``data_dir`` (of ``skills`` only if given), sorted."""
    read_manifest(data_dir)
    root = Path(data_dir)
    names = sorted(p.name for p in root.iterdir() if p.is_dir()) if skills is None else list(skills)
    return [p for name in names for p in sorted((root / name).glob("demo_*.npz")) if DEMO_PATTERN.match(p.name)]


def load_demo(path: str | Path) -> Demo:
    """Read one ``demo_NNNNN.npz`` (never unpickles) and check its arrays."""
    path = Path(path)
    match = DEMO_PATTERN.match(path.name)
    try:
        with np.load(path, allow_pickle=False) as f:
            arrays = {k: f[k] for k in f.files}
    except (OSError, ValueError) as exc:
        raise InputError(f"cannot read demonstration {path}: {exc}") from None
    missing = [k for k in (*REQUIRED, "skill", "params") if k not in arrays]
    if missing:
        raise InputError(f"demonstration {path} lacks arrays {missing}")
    for key, ndim in REQUIRED.items():
        if arrays[key].ndim != ndim:
            raise InputError(f"demonstration {path}: '{key}' must have {ndim} axes, got shape {arrays[key].shape}")
    dough = arrays["dough"].astype(np.float32, copy=False)
    if dough.shape[-1] != 3 or dough.shape[0] < 1 or not np.isfinite(dough).all():
        raise InputError(f"demonstration {path}: dough must be finite (T+1, P, 3), got shape {dough.shape}")
    params = json.loads(str(arrays["params"])) if str(arrays["params"]) else {}
    return Demo(
        skill=str(arrays["skill"]),
        index=int(match.group(1)) if match else 0,
        dough=dough,
        tool_points=arrays["tool_points"].astype(np.float32, copy=False),
        tool_pose=arrays["tool_pose"].astype(np.float32, copy=False),
        action=arrays["action"].astype(np.float32, copy=False),
        params=params,
        path=str(path),
        final_dough=_final_dough(arrays, path),
    )


def _final_dough(arrays: dict, path: Path) -> np.ndarray | None:
    if "final_dough" not in arrays:
        return None
    final = arrays["final_dough"].astype(np.float32, copy=False)
    if final.ndim != 2 or final.shape[-1] != 3 or len(final) == 0 or not np.isfinite(final).all():
        raise InputError(f"demonstration {path}: final_dough must be finite (P, 3), got shape {final.shape}")
    return final


def load_demos(data_dir: str | Path, skills: Iterable[str] | None = None, *, stage: str | None = None) -> list[Demo]:
    """Every demonstration under ``data_dir`` (of ``skills`` if given).

    ``stage``: the training stage that reads them (``vae``, ``feasibility``, ``cost``, ``policy``, ``reset``);
    a demonstration whose scene variant keeps it for some stages only (its ``params["stages"]``, written by
    ``pasta demos`` from :attr:`pasta.core.DemoVariant.stages`) is left out of the others.

    Raises:
        InputError: no demonstration found.
    """
    skills = list(skills) if skills is not None else None
    paths = demo_paths(data_dir, skills)
    which = f" of skill(s) {', '.join(skills)}" if skills else ""
    if not paths:
        fix = f"; generate them with `pasta demos skill={skills[0]} out={data_dir}`" if skills else ""
        raise InputError(f"no demonstrations{which} under {data_dir} (expected <skill>/demo_00000.npz files){fix}")
    if stage is not None:
        paths = [p for p in paths if stage in _stages(p, stage)]
        if not paths:
            raise InputError(f"no demonstrations{which} under {data_dir} are for training stage '{stage}' "
                             "(all of them belong to scene variants kept for other stages)")
    return [load_demo(p) for p in paths]


def _stages(path: Path, default: str) -> Sequence[str]:
    """The training stages a demonstration is for (its ``params["stages"]``; ``(default,)`` when it names
    none), read without loading its arrays."""
    try:
        with np.load(path, allow_pickle=False) as f:
            params = str(f["params"]) if "params" in f.files else ""
    except (OSError, ValueError) as exc:
        raise InputError(f"cannot read demonstration {path}: {exc}") from None
    return json.loads(params).get("stages", (default,)) if params else (default,)


def split_by_demo(demos: Sequence[Demo], *, val_fraction: float = 0.2, seed: int = 0) -> tuple[list[Demo], list[Demo]]:
    """Split into (train, validation) by whole demonstration, per skill, with a seeded shuffle.

    Every skill with at least two demonstrations gives at least one to validation and keeps at least
    one for training; a skill with one demonstration keeps it for training.
    """
    train, val = [], []
    by_skill: dict[str, list[Demo]] = {}
    for demo in demos:
        by_skill.setdefault(demo.skill, []).append(demo)
    for skill in sorted(by_skill):
        group = sorted(by_skill[skill], key=lambda d: d.index)
        order = np.random.default_rng([seed, _stable_hash(skill)]).permutation(len(group))
        n_val = 0 if len(group) < 2 else min(len(group) - 1, max(1, round(val_fraction * len(group))))
        val += [group[i] for i in order[:n_val]]
        train += [group[i] for i in order[n_val:]]
    return train, val


def _stable_hash(text: str) -> int:
    return int.from_bytes(text.encode()[:8].ljust(8, b"\0"), "little")


@dataclass
class DemoEntities:
    """Entities of every step of one demonstration.

    Attributes:
        demo: the demonstration's key (``"cut/00003"``).
        skill: its skill.
        clouds: per step ``t``, an array ``(K_t, P_e, 3)`` of entity clouds.
    """

    demo: str
    skill: str
    clouds: list[np.ndarray]


def demo_entities(
    demo: Demo, *, num_points: int = 1000, min_points: int = 10, stride: int = 1, seed: int = 0
) -> DemoEntities:
    """Decompose every ``stride``-th step of ``demo`` (and the last) into entities of ``num_points`` points."""
    from pasta.core.decompose import decompose

    steps = list(range(0, len(demo.dough), max(1, stride)))
    if steps[-1] != len(demo.dough) - 1:
        steps.append(len(demo.dough) - 1)
    clouds = [
        np.stack(decompose(demo.dough[t], min_points=min_points, num_points=num_points, seed=seed + t)) for t in steps
    ]
    return DemoEntities(demo.key, demo.skill, clouds)
