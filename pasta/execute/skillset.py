"""Which registered skills a command plans with: ``skills=`` or every skill that has trained weights.

``pasta run``, ``pasta eval`` and ``pasta plan`` all decide through :func:`choose_skills`, so they agree.
A skill needs, under the models root:

- a feasibility network ``ROOT/feasibility/<skill>`` unless its class implements ``feasibility`` itself
  (the Flat 3D method always needs ``ROOT/flat/feasibility/<skill>``);
- with learned controllers (``controller=learned``), a policy ``ROOT/policy/<skill>``.

Without ``skills=``, skills missing any of these are left out and :meth:`SkillChoice.warning` names them
with the commands that train them; a skill named in ``skills=`` that misses one is an error. The decision
only looks for the checkpoint files; loading them (and rejecting incompatible ones) is the loaders' job.

Given the scene (:class:`~pasta.core.Scene`: the task's, or ``pasta plan``'s ``scene=``), a skill whose needs
it does not meet (:attr:`pasta.core.SkillSpec.needs`: a static tool, a raised surface, its own tool) is
never planned: left out with the reason (:meth:`SkillChoice.scene_note`), and an error when ``skills=`` or
the skeleton names it. Registering a skill therefore never widens the search of a scene it cannot act in.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pasta.core.errors import ConfigError, MissingComponentError

if TYPE_CHECKING:
    from pasta.core import Scene, Skill

__all__ = ["SkillChoice", "choose_skills", "needs_feasibility_network", "parse_skill_names"]


@dataclass
class SkillChoice:
    """The outcome of :func:`choose_skills`.

    Attributes:
        names: the chosen skills, in registry order (or in the order ``skills=`` gave them).
        left_out: skill -> what it lacks, one ``"<module> (ROOT/...): train with `...`"`` entry per
            missing checkpoint; empty when ``skills=`` was given.
        root: the models root that was searched.
        scene: the scene the skills were fitted to (``None``: every skill allowed).
        unmet: skill -> why the scene does not allow it (:meth:`pasta.core.SceneNeeds.unmet`).
    """

    names: list[str]
    root: Path
    left_out: dict[str, list[str]] = field(default_factory=dict)
    scene: Scene | None = None
    unmet: dict[str, list[str]] = field(default_factory=dict)

    def require(self, needed: Sequence[str], what: str) -> None:
        """Raise :class:`ConfigError` when a skill of ``needed`` (used by ``what``) is not chosen, saying why."""
        missing = [n for n in dict.fromkeys(needed) if n not in self.names]
        if not missing:
            return
        reasons = [f"'{n}': " + ("; ".join(self.left_out[n]) if n in self.left_out else
                                 f"the scene ({self.scene.describe() if self.scene else ''}) does not allow it: "
                                 + "; ".join(self.unmet[n]) if n in self.unmet else "not in skills=") for n in missing]
        raise ConfigError(f"{what} needs the skills {', '.join(dict.fromkeys(needed))}; left out: {'; '.join(reasons)}. "
                          f"Chosen skills: {', '.join(self.names)}")

    def record(self) -> dict[str, Any] | None:
        """The scene the skills were fitted to and the skills it left out, with why, as JSON (``None``: no scene)."""
        if self.scene is None:
            return None
        scene = self.scene
        return {"source": scene.source, "static": list(scene.static), "surfaces": list(scene.surfaces),
                "left_out": {name: list(why) for name, why in self.unmet.items()}}

    def scene_note(self) -> str | None:
        """One line: the scene and the skills it leaves out, with why (``None`` without a scene)."""
        if self.scene is None:
            return None
        line = f"scene: {self.scene.describe()}"
        if self.unmet:
            line += "; left out: " + "; ".join(f"{name} ({', '.join(why)})" for name, why in self.unmet.items())
        return line

    def warning(self) -> str | None:
        """One line naming the left-out skills and the commands that train them (``None`` if none)."""
        if not self.left_out:
            return None
        from pasta.weights import train_into

        missing = "; ".join(f"{name}: {', '.join(needs)}" for name, needs in self.left_out.items())
        out, then = train_into(self.root)
        return (f"warning: skills without trained weights under {self.root} are left out: "
                f"{', '.join(self.left_out)} ({missing}); or `pasta pipeline skills={','.join(self.left_out)} "
                f"out={out}` trains everything they need{then}")


def parse_skill_names(value: str | Sequence[str] | None) -> list[str]:
    """``"cut,push"`` (or a list) -> ``["cut", "push"]``; ``None``/``""`` -> ``[]`` (no choice given)."""
    if value is None:
        return []
    items = value.split(",") if isinstance(value, str) else list(value)
    names = [n.strip() for n in items if n.strip()]
    repeated = sorted({n for n in names if names.count(n) > 1})
    if repeated:
        raise ConfigError(f"skills= names {', '.join(repeated)} more than once")
    return names


def choose_skills(requested: str | Sequence[str] | None, root: str | Path, *, plugins: Any = None,
                  policy: bool = False, flat: bool = False, scene: Scene | None = None) -> SkillChoice:
    """The skills to plan with, given ``skills=`` (``requested``) and the models under ``root``.

    Args:
        requested: ``"cut,push,roll"``, a list of names, or ``None``/``""`` for every registered skill
            that has its weights.
        root: models root (``pasta train ... out=ROOT``, or the shipped :data:`pasta.weights.ROOT`).
        policy: learned controllers will run, so every skill needs its policy.
        flat: the Flat 3D method (scene feasibility networks under ``ROOT/flat``).
        scene: the resolved scene (:func:`pasta.tasks.scene.resolve_scene`); skills whose needs it does not
            meet are left out (``None``: no scene check).

    Raises:
        PluginNotFoundError: a requested name is not a registered skill (the known ones are listed).
        ConfigError: ``requested`` names a skill the scene does not allow (saying why).
        MissingComponentError: a requested skill lacks weights (the message gives the training command),
            or no registered skill has them.
    """
    if plugins is None:
        from pasta.plugins import get_plugins

        plugins = get_plugins()
    root = Path(root)
    names = parse_skill_names(requested)
    for name in names:
        plugins.skills.info(name)  # unknown -> PluginNotFoundError listing the registered skills
    candidates = names or plugins.skills.names()
    unmet: dict[str, list[str]] = {}
    if scene is not None:
        from pasta.tasks.scene import scene_fit

        unmet = scene_fit(candidates, scene, plugins.skills)
        if names and unmet:
            detail = "; ".join(f"'{name}': {', '.join(why)}" for name, why in unmet.items())
            raise ConfigError(f"skills= names skills the scene ({scene.describe()}) does not allow: {detail}")
        candidates = [n for n in candidates if n not in unmet]
    lacking = {name: _missing(plugins.skills.load(name), root, policy=policy, flat=flat) for name in candidates}
    lacking = {name: needs for name, needs in lacking.items() if needs}
    if names and lacking:
        detail = "; ".join(f"skill '{name}' has no {', '.join(needs)}" for name, needs in lacking.items())
        raise MissingComponentError(f"skills= names skills without trained weights under {root}: {detail}")
    chosen = [n for n in candidates if n not in lacking]
    if not candidates and unmet:
        detail = "; ".join(f"{name}: {', '.join(why)}" for name, why in unmet.items())
        raise ConfigError(f"the scene ({scene.describe() if scene else ''}) allows none of the skills ({detail})")
    if not chosen:
        detail = "; ".join(f"{name}: {', '.join(needs)}" for name, needs in lacking.items())
        raise MissingComponentError(f"no registered skill has trained weights under {root} ({detail or 'no skills registered'})")
    return SkillChoice(chosen, root, lacking, scene, unmet)


def needs_feasibility_network(skill: Any) -> bool:
    """Whether ``skill`` (an instance or class) gets its feasibility from a trained network, i.e. does not
    implement :meth:`pasta.core.Skill.feasibility` itself and has no network attached yet."""
    from pasta.core import Skill

    cls: type[Skill] = skill if isinstance(skill, type) else type(skill)
    return cls.feasibility is Skill.feasibility and getattr(skill, "feasibility_model", None) is None


def _missing(cls: type[Skill], root: Path, *, policy: bool, flat: bool) -> list[str]:
    """What skill class ``cls`` lacks under ``root``: one ``what (where): train with `cmd``` entry per checkpoint."""
    from pasta.io.checkpoint import checkpoint_exists
    from pasta.nn import FEASIBILITY_DIR
    from pasta.policy import POLICY_DIR
    from pasta.weights import module_dir, train_into

    name = cls.spec.name
    out, then = train_into(root)
    needs = []
    if flat:
        from pasta.nn.flat import flat_hint

        where = root / "flat" / FEASIBILITY_DIR / name
        if not checkpoint_exists(where):
            needs.append(f"Flat 3D feasibility network ({where}): train with "
                         f"{flat_hint('feasibility', Path(out) / 'flat', name)}{then}")
    elif needs_feasibility_network(cls):
        where = module_dir(root, f"{FEASIBILITY_DIR}/{name}")
        if not checkpoint_exists(where):
            needs.append(f"feasibility network ({where}): train with "
                         f"`pasta train feasibility data=DIR out={out} skill={name}`{then}")
    if policy:
        where = module_dir(root, f"{POLICY_DIR}/{name}")
        if not checkpoint_exists(where):
            needs.append(f"policy ({where}): train with `pasta train policy data=DIR out={out} skill={name}`{then}")
    return needs
