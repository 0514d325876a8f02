"""Which skills can make demonstrations, the scenes they start from, and the public scene helpers.

A skill makes demonstrations when its class overrides the hooks of :attr:`pasta.core.Skill.DEMO_HOOKS`
(:meth:`~pasta.core.Skill.has_expert`): ``demo_scene`` gives the boxes of dough a demonstration starts
from, ``sample_expert_params`` / ``expert_approach_pose`` / ``expert`` run it; or, without a scripted expert,
those of :attr:`pasta.core.Skill.GBTO_HOOKS` (:meth:`~pasta.core.Skill.has_gbto`): ``demo_target`` says what
the step should leave and trajectory optimisation finds the actions. Scene variants
(:attr:`~pasta.core.Skill.demo_variants`, ``pasta demos scene=NAME``) change the scene and the expert's
config. Nothing here names a skill: everything comes from what is registered.

Scene helpers shared by task plugins and skill plugins' demonstration scenes (a scene is a list of boxes
``[(centre (3,), size (3,))]``; unit cube, y up, ``floor`` the height the dough rests on): :func:`crs_box`
(the CRS dough), :func:`small_box` (a piece like the one a cut leaves), :func:`lumps` (three lumps in a
row), the spreading area :data:`SPREAD_X` and the dough height :data:`HEIGHT`; :func:`standing_tool` (from
:mod:`pasta.tasks.scene`) finds a static tool that another plugin registers (the raised board) and where it stands. Tasks and demonstrations
draw from the same samplers, so the scenes a skill is trained on are the scenes its tasks show.
"""

from __future__ import annotations

from dataclasses import fields, is_dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from pasta.core.errors import ConfigError, InputError, PastaError, did_you_mean
from pasta.tasks.scene import standing_tool as standing_tool  # re-exported: the scene helpers plugins use

if TYPE_CHECKING:
    from pasta.core import Skill

DEFAULT = "default"


def demo_skills(plugins: Any = None) -> list[str]:
    """Names of the registered skills that can make demonstrations (sorted); skills whose class does not
    import are left out (``pasta plugins`` reports them)."""
    if plugins is None:
        from pasta.plugins import get_plugins

        plugins = get_plugins()
    names = []
    for name in plugins.skills.names():
        try:
            cls = plugins.skills.load(name)
        except PastaError:
            continue
        if cls.has_expert() or cls.has_gbto():
            names.append(name)
    return names


def check_demo_skill(name: str, plugins: Any = None) -> type:
    """The class of skill ``name`` if it can make demonstrations.

    Raises:
        ConfigError: ``name`` is not registered, or its plugin lacks demonstration hooks (named), with the
            list of skills that have them.
    """
    if plugins is None:
        from pasta.plugins import get_plugins

        plugins = get_plugins()
    able = demo_skills(plugins)
    known = f"skills with demonstrations: {', '.join(able) or 'none'}"
    if name not in plugins.skills:
        raise ConfigError(f"unknown skill '{name}' for demonstrations{did_you_mean(name, able)}; {known}")
    cls = plugins.skills.load(name)
    if not (cls.has_expert() or cls.has_gbto()):
        raise ConfigError(f"skill '{name}' cannot make demonstrations: its plugin defines neither a scripted expert "
                          f"(missing {', '.join(cls.missing_demo_hooks())}) nor a target for trajectory optimisation "
                          f"(missing {', '.join(cls.missing_gbto_hooks())}) (pasta.core.Skill hooks); {known}")
    return cls


def variants(cls: type[Skill]) -> list[str]:
    """Scene variants of a skill class: ``"default"`` and the keys of its ``demo_variants``."""
    return [DEFAULT, *(v for v in cls.demo_variants if v != DEFAULT)]


def check_variant(cls: type[Skill], variant: str) -> None:
    """Raise :class:`ConfigError` unless ``variant`` is one of :func:`variants` of ``cls``."""
    if variant not in variants(cls):
        raise ConfigError(f"skill '{cls.spec.name}' has no demonstration scene '{variant}'; "
                          f"its scenes: {', '.join(variants(cls))}")


def variant_config(config: Any, cls: type[Skill], variant: str) -> Any:
    """``config`` with the fields a variant sets (:attr:`pasta.core.DemoVariant.config`) replaced."""
    check_variant(cls, variant)
    if variant == DEFAULT or not cls.demo_variants[variant].config:
        return config
    changes = dict(cls.demo_variants[variant].config)
    names = {f.name for f in fields(config)} if is_dataclass(config) else set()
    unknown = sorted(set(changes) - names)
    if unknown:
        raise ConfigError(f"skill '{cls.spec.name}': demonstration scene '{variant}' sets unknown config fields {unknown}")
    return replace(config, **changes)


def scene_boxes(skill: Any, rng: np.random.Generator, floor_y: float, variant: str = DEFAULT) -> list[tuple]:
    """The skill's demonstration scene, checked: ``n_in`` boxes ``[(centre (3,), size (3,))]``, sizes > 0."""
    check_variant(type(skill), variant)
    boxes = list(skill.demo_scene(rng, floor_y, variant))
    if len(boxes) != skill.n_in:
        raise InputError(f"skill '{skill.name}' consumes {skill.n_in} piece(s) but its demo_scene returned "
                         f"{len(boxes)} box(es)")
    for box in boxes:
        try:
            centre, size = (np.asarray(v, np.float64) for v in box)
        except (TypeError, ValueError):
            raise InputError(f"skill '{skill.name}': demo_scene must return (centre, size) pairs, got {box!r}") from None
        if centre.shape != (3,) or size.shape != (3,) or not (size > 0).all() or not np.isfinite(centre).all():
            raise InputError(f"skill '{skill.name}': demo_scene box {box!r} needs a centre (3,) and a size (3,) > 0")
    return boxes


def scene_particles(boxes: list[tuple], n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """``(n, 3)`` float32 particles of ``boxes`` split by volume (the first box takes the remainder),
    and ``(n,)`` the box each belongs to. One box: exactly ``box_particles(centre, size, n, rng)``."""
    from pasta.sim import box_particles

    vols = np.array([np.prod(s) for _, s in boxes], np.float64)
    counts = np.floor(n * vols / vols.sum()).astype(int)
    counts[0] += n - counts.sum()
    if (counts < 1).any():
        raise InputError(f"{n} particles leave a box of the scene empty (box volumes {vols.tolist()})")
    parts = [box_particles(c, s, int(k), rng) for (c, s), k in zip(boxes, counts)]
    owner = np.concatenate([np.full(int(k), i) for i, k in enumerate(counts)])
    return np.concatenate(parts), owner


# -- scene helpers ---------------------------------------------------------------------------------------
#: x range of the spreading area (where pieces are rolled flat)
SPREAD_X = (0.22, 0.32)
#: height of the CRS dough and of the small pieces cut off it
HEIGHT = 0.08


def crs_box(rng: np.random.Generator, floor: float, length: tuple[float, float] = (0.2, 0.35),
            z_spread: float = 0.2) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """(centre, size) of the CRS dough: at the right end of the workspace, resting on the floor."""
    length_ = rng.uniform(*length)
    depth = rng.uniform(0.06, 0.08)
    z = 0.5 + rng.uniform(-z_spread, z_spread)
    return (0.9 - length_ / 2, floor + HEIGHT / 2, z), (length_, HEIGHT, depth)


def small_box(rng: np.random.Generator, floor: float, x: tuple[float, float], z: tuple[float, float]):
    """(centre, size) of a small piece like the one a cut leaves: x-length U(0.1, 0.12), depth U(0.06, 0.08)."""
    size = (rng.uniform(0.1, 0.12), HEIGHT, rng.uniform(0.06, 0.08))
    return (rng.uniform(*x), floor + HEIGHT / 2, rng.uniform(*z)), size


def lumps(rng: np.random.Generator, floor_y: float, x: tuple[float, float], z: tuple[float, float]) -> list:
    """Three dough lumps ``[(centre, size)]`` in a row along x: sides U(0.04, 0.05) (height 0.04-0.05),
    3.5-5 cm apart (more than DBSCAN's 3 cm: three entities), each shifted up to 2 cm in z; the row's
    middle at x in ``x``, z in ``z``."""
    sides = rng.uniform(0.04, 0.05, size=3)
    gaps = rng.uniform(0.035, 0.05, size=2)
    span = float(sides.sum() + gaps.sum())
    left = float(rng.uniform(*x)) - span / 2
    zc = float(rng.uniform(*z))
    out = []
    for i, s in enumerate(sides):
        cx = left + float(sides[:i].sum() + gaps[:i].sum()) + s / 2
        h = float(s)
        out.append(((cx, floor_y + h / 2, zc + float(rng.uniform(-0.02, 0.02))), (float(s), h, float(s))))
    return out
