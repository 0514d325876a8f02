"""The Flat 3D baseline: the whole dough scene is ONE latent, so every skill is ``1 -> 1``.

The pipeline is PASTA's, without the decomposition into pieces: the ``flat`` encoder
(:class:`~pasta.nn.encoders.FlatEncoder`, ``scope == "scene"``) encodes the whole observed cloud,
each skill's feasibility scores (scene before, scene after), and the cost compares scene latents.
:func:`pasta.execute.episode.perceive` and the executor already treat a ``scene`` encoder as "the
whole cloud is one entity".

Models root (default :data:`pasta.nn.FLAT_ROOT`, ``models/flat``), the same sub-directories as an
entity root, trained with ``out=ROOT flat=true``::

    ROOT/vae/                 pasta train vae         data=DIR out=ROOT flat=true
    ROOT/feasibility/<skill>/ pasta train feasibility data=DIR out=ROOT flat=true skill=<skill>
    ROOT/cost/                pasta train cost        data=DIR out=ROOT flat=true

Use::

    encoder, cost, skills = load_flat("models/flat", [task.skill(n) for n in ("cut", "push", "roll")])
    plan = perceive_and_plan(obs, goal, planner=planner, skills=skills, encoder=encoder, cost=cost, horizon=3).plan
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import Any, ClassVar

from pasta.core.errors import MissingComponentError
from pasta.core.skill import Skill, SkillSpec
from pasta.nn import COST_DIR, FEASIBILITY_DIR, FLAT_ROOT, VAE_DIR

__all__ = ["FlatSkill", "flat_hint", "flat_skill", "flat_skills", "load_flat", "load_flat_encoder"]


def flat_hint(module: str, root: str | Path = FLAT_ROOT, skill: str = "NAME") -> str:
    """The command that trains the Flat 3D ``module`` (``vae``, ``feasibility`` or ``cost``) into ``root``."""
    extra = {"vae": "", "feasibility": f" skill={skill}", "cost": ""}[module]
    return f"`pasta train {module} data=DIR out={root} flat=true{extra}`"


class FlatSkill(Skill):
    """A skill seen as ``1 -> 1`` (scene before -> scene after), delegating its acting to the wrapped skill.

    The flat skill has its own feasibility network (:meth:`attach_feasibility`); everything else
    (approach and parking poses, expert, heuristic controller, learned policy, ``max_steps``, the
    config...) is the wrapped skill's. Build one with :func:`flat_skill`, which gives every wrapped
    skill a class whose :attr:`spec` has its name and tool and ``n_in = n_out = 1``.
    """

    spec: ClassVar[SkillSpec]

    def __init__(self, wrapped: Skill) -> None:
        super().__init__(wrapped.config)
        self.__dict__["wrapped"] = wrapped

    # the learned policy belongs to the wrapped skill (a policy loader may attach it to either)
    @property
    def policy_model(self) -> Any:
        return self.wrapped.policy_model

    @policy_model.setter
    def policy_model(self, value: Any) -> None:
        if "wrapped" in self.__dict__:  # Skill.__init__ sets None before the wrapped skill is known
            self.wrapped.policy_model = value

    def attach_policy(self, model: Any) -> None:
        self.wrapped.attach_policy(model)

    def policy(self) -> Any:
        return self.wrapped.policy()

    def approach_pose(self, *args: Any, **kwargs: Any) -> Any:
        return self.wrapped.approach_pose(*args, **kwargs)

    def park_pose(self, *args: Any, **kwargs: Any) -> Any:
        return self.wrapped.park_pose(*args, **kwargs)

    def sample_expert_params(self, *args: Any, **kwargs: Any) -> Any:
        return self.wrapped.sample_expert_params(*args, **kwargs)

    def expert(self, *args: Any, **kwargs: Any) -> Any:
        return self.wrapped.expert(*args, **kwargs)

    def controller(self, *args: Any, **kwargs: Any) -> Any:
        return self.wrapped.controller(*args, **kwargs)

    def __getattr__(self, name: str) -> Any:  # only reached for what Skill itself lacks (max_steps...)
        if name == "wrapped" or name.startswith("__"):
            raise AttributeError(name)
        return getattr(self.wrapped, name)

    def __repr__(self) -> str:
        return f"FlatSkill({self.name}: 1 -> 1 scene, tool={self.tool}, wraps {self.wrapped!r})"


_CLASSES: dict[SkillSpec, type[FlatSkill]] = {}


def flat_skill(skill: Skill) -> FlatSkill:
    """``skill`` as a new ``1 -> 1`` :class:`FlatSkill` of the same name and tool (a flat skill: its wrapped one)."""
    if isinstance(skill, FlatSkill):
        skill = skill.wrapped
    s = skill.spec
    spec = SkillSpec(s.name, 1, 1, s.tool, f"Flat 3D ({s.n_in} -> {s.n_out} pieces as scene -> scene): {s.description}")
    if spec not in _CLASSES:
        _CLASSES[spec] = type(f"Flat{type(skill).__name__}", (FlatSkill,), {"spec": spec, "__module__": __name__})
    return _CLASSES[spec](skill)


def flat_skills(skills: Iterable[Skill]) -> list[Skill]:
    """Every skill of ``skills`` as a ``1 -> 1`` :class:`FlatSkill` (see :func:`flat_skill`), in order."""
    return [flat_skill(s) for s in skills]


def load_flat_encoder(root: str | Path = FLAT_ROOT, *, vae: str | Path = "", device: str = "cpu") -> Any:
    """The ``flat`` encoder (:class:`~pasta.nn.encoders.FlatEncoder`) of ``vae`` (default ``root/vae``).

    Raises:
        MissingComponentError: no trained scene VAE there (the message gives the command).
        IncompatibleCheckpointError: the VAE there is not a scene VAE (e.g. an entity root).
    """
    from pasta.nn.config import FlatEncoderConfig
    from pasta.nn.encoders import FlatEncoder

    path = Path(vae) if str(vae) else Path(root) / VAE_DIR
    try:
        return FlatEncoder(FlatEncoderConfig(weights=str(path), device=device))
    except MissingComponentError:
        raise MissingComponentError(
            f"Flat 3D: no scene VAE at {path}: train it with {flat_hint('vae', path.parent)}"
        ) from None


def load_flat(root: str | Path, skills: Iterable[Skill], *, device: str = "cpu") -> tuple[Any, Any, list[Skill]]:
    """The Flat 3D models under ``root``: ``(encoder, cost_model, flat_skills)``.

    ``encoder`` is the ``flat`` encoder of ``root/vae`` (``scope == "scene"``), ``cost_model`` the
    ``set_cost`` model of ``root/cost`` and ``flat_skills`` :func:`flat_skills` of ``skills`` with
    ``root/feasibility/<skill>`` attached (``skills`` themselves are not changed).

    Raises:
        MissingComponentError: a module is not trained (the message names the command).
        IncompatibleCheckpointError: a module there is not a Flat 3D one, or does not fit the encoder.
    """
    from pasta.nn.config import SetCostConfig
    from pasta.nn.cost import SetCostModel, load_pair_cost
    from pasta.nn.loading import load_feasibility

    root = Path(root)
    encoder = load_flat_encoder(root, device=device)
    d = encoder.latent_dim
    try:
        pair = load_pair_cost(str(root / COST_DIR), device=device, latent_dim=d, scope="scene")
    except MissingComponentError:
        raise MissingComponentError(
            f"Flat 3D: no cost network at {root / COST_DIR}: train it with {flat_hint('cost', root)}"
        ) from None
    cost = SetCostModel(SetCostConfig(weights=str(root / COST_DIR), device=device), model=pair)
    out = flat_skills(skills)
    for skill in out:
        where = root / FEASIBILITY_DIR / skill.name
        try:
            model = load_feasibility(where, skill=skill.name, n_in=1, n_out=1, latent_dim=d, device=device,
                                     scope="scene")
        except MissingComponentError:
            raise MissingComponentError(
                f"Flat 3D: skill '{skill.name}' has no feasibility network at {where}: "
                f"train it with {flat_hint('feasibility', root, skill.name)}"
            ) from None
        skill.attach_feasibility(model)
    return encoder, cost, out
