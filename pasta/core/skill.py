"""The Skill contract: a tool behaviour that consumes ``N_k`` dough entities and produces ``M_k``.

A skill bundles three roles, each filled by a later component and each optional until a call needs it:

- cardinality and tool (:class:`SkillSpec`): known without importing torch or taichi, so the plugin
  registry can list skills cheaply and the planner can enumerate skill sequences;
- feasibility ``f_k(U_in (B, N, D), U_out (B, M, D)) -> (B,)`` in ``[0, 1]``: a learned set network
  attached with :meth:`Skill.attach_feasibility`;
- controllers that act in the simulator: the scripted ``expert`` (demonstrations and goals), the
  point-cloud ``controller`` (heuristic) and the learned ``policy``, all behind :class:`Controller`;
- demonstrations: the scene a demonstration starts from (:meth:`Skill.demo_scene`, with optional
  :attr:`Skill.demo_variants`) and the skill's training settings (:attr:`Skill.training_defaults`).

Calls whose component is missing raise :class:`~pasta.core.errors.MissingComponentError` naming it.
"""

from __future__ import annotations

import re
from abc import ABC, abstractmethod
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar

from pasta.core.errors import InputError, MissingComponentError, PluginValidationError
from pasta.core.scene import SceneNeeds
from pasta.core.step import Stop

if TYPE_CHECKING:
    import numpy as np
    import torch

_NAME = re.compile(r"^[a-z][a-z0-9_]*$")


@dataclass(frozen=True)
class SkillSpec:
    """What the planner needs to know about a skill before any network exists.

    Attributes:
        name: registry name, lower case (``"cut"``).
        n_in: ``N_k``, entities the skill consumes (>= 1).
        n_out: ``M_k``, entities the skill produces (>= 1).
        tool: simulator tool the skill drives (``"knife"``).
        description: one line for ``pasta plugins``.
        needs: what the skill needs from the scene besides its tool (:class:`~pasta.core.SceneNeeds`); the
            planner never considers the skill in a scene that does not meet them.
    """

    name: str
    n_in: int
    n_out: int
    tool: str
    description: str = ""
    needs: SceneNeeds = field(default_factory=SceneNeeds)

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not _NAME.match(self.name):
            raise PluginValidationError(
                f"skill name {self.name!r} must be lower case letters, digits and '_', starting with a letter"
            )
        for attr, value in (("n_in", self.n_in), ("n_out", self.n_out)):
            if not isinstance(value, int) or isinstance(value, bool) or value < 1:
                raise PluginValidationError(f"skill '{self.name}': {attr} must be an integer >= 1, got {value!r}")
        if not isinstance(self.tool, str) or not self.tool:
            raise PluginValidationError(f"skill '{self.name}': tool must be a non-empty string, got {self.tool!r}")
        if not isinstance(self.needs, SceneNeeds):
            raise PluginValidationError(f"skill '{self.name}': needs must be a pasta.core.SceneNeeds, got {self.needs!r}")

    @property
    def delta(self) -> int:
        """Change in the number of entities, ``M_k - N_k``."""
        return self.n_out - self.n_in


@dataclass
class SkillObservation:
    """What a controller sees at one environment step (all ``np.ndarray``, float32).

    Attributes:
        piece: ``(P, 3)`` points of the attended dough piece(s).
        goal: ``(G, 3)`` points of the step's sub-goal (all produced entities together); ``None`` for
            scripted experts, which need none.
        tool_points: ``(T, 3)`` surface points of the skill's tool.
        tool_pose: ``(7,)`` tool position and unit quaternion (w, x, y, z).
        scene: ``(S, 3)`` the whole observed dough, for controllers that must avoid other pieces.
    """

    piece: np.ndarray
    goal: np.ndarray | None
    tool_points: np.ndarray
    tool_pose: np.ndarray
    scene: np.ndarray | None = None


#: a dough box of a demonstration scene: ``(centre (x, y, z), size (dx, dy, dz))``, full extents, metres
SceneBox = tuple[tuple[float, float, float], tuple[float, float, float]]


@dataclass(frozen=True)
class DemoVariant:
    """A demonstration scene distribution a skill offers besides ``"default"`` (``pasta demos scene=NAME``).

    Declared in :attr:`Skill.demo_variants`; :meth:`Skill.demo_scene` receives the name.

    Attributes:
        config: skill config fields the expert uses in this variant, ``{field: value}`` (e.g. a wider
            target box), applied with :func:`dataclasses.replace` to the skill's default config.
        pipeline_demos: demonstrations ``pasta pipeline`` adds in this variant after the default ones
            (unit ``demos/<skill>-<name>``, same folder, the following indices; 0: the pipeline makes none).
        description: one line for listings and errors.
        stages: the training stages that learn from these demonstrations (``vae``, ``feasibility``,
            ``cost``, ``policy``, ``reset``); empty (the default): all of them. Recorded in each
            demonstration's ``params["stages"]``; the readers of the other stages leave it out (e.g. demos
            that teach the learned reset pose a wider range without changing the policy or the planner's
            networks).
    """

    config: Mapping[str, Any] = field(default_factory=dict)
    pipeline_demos: int = 0
    description: str = ""
    stages: tuple[str, ...] = ()


@dataclass(frozen=True)
class ToolPose:
    """A tool placement: ``position`` (x, y, z) and rotation ``yaw`` about the vertical axis (radians)."""

    position: tuple[float, float, float]
    yaw: float = 0.0


class Controller(ABC):
    """Closed-loop driver of one skill execution: observation in, tool action ``(A,)`` and a stop reason out.

    The step loop (:func:`pasta.tasks.step.run_skill`) and its :class:`~pasta.core.step.StepMonitor` decide
    when the step ends; the controller says what it knows: that its skill is finished (``Stop.DONE``, or
    ``True``) or that it used up its own action budget (``Stop.CAP``).
    """

    #: whether the step monitor watches this controller's progress towards the goal instead of trusting
    #: its stop: ``True`` for learned policies (their done head can stay low while they push a piece past
    #: its goal); the monitor then may skip a step whose piece is at its goal, end a step whose piece moves
    #: away from it again, and run a capped step on while its piece still closes on its goal
    watch: ClassVar[bool] = False

    def reset(self, obs: SkillObservation) -> None:  # noqa: B027 - optional hook
        """Called once before the first :meth:`act` of an execution."""

    @abstractmethod
    def act(self, obs: SkillObservation) -> tuple[np.ndarray, Stop | bool | None]:
        """Return the action ``(A,)`` in ``[-1, 1]`` and ``None`` (go on) or why the controller stops:
        ``Stop.DONE`` (or ``True``) when its skill is finished, ``Stop.CAP`` when it reached its own action
        budget. A stop with an all-zero action ends the step before the action is applied; with another
        action, the action is applied first (the last action of a demonstration)."""


class Skill:
    """Base class of every skill plugin. Subclasses set :attr:`spec` and override the hooks they fill.

    Args:
        config: the skill's own settings (a dataclass instance or ``None``).
    """

    spec: ClassVar[SkillSpec]
    #: half width (metres) of the band the tool sweeps across its motion when it moves a piece; the
    #: planner's clearance check (pasta.planning.clearance) widens a moved piece to at least this
    sweep_half_width: ClassVar[float] = 0.0
    #: the skill (1 -> 1) leaves its piece's horizontal centroid about where it was (a roll spreads the
    #: piece where it lies): the executor then aims an earlier step at the goal piece's place directly
    keeps_position: ClassVar[bool] = False
    #: Chamfer distance within which a watched (learned) step of this skill that keeps the piece count finds
    #: its piece at its goal, so the step is not started (``None``: ``perception.unchanged_threshold``), unless
    #: :meth:`unfinished` says otherwise. A skill whose smallest real change is larger says so: a roll cannot
    #: flatten an already rolled piece, only spread it again
    at_goal: ClassVar[float | None] = None
    #: demonstration scene variants besides ``"default"``: name -> :class:`DemoVariant`
    demo_variants: ClassVar[Mapping[str, DemoVariant]] = {}
    #: ``pasta pipeline`` settings of this skill's units, ``{stage: {key: value}}``, over the stage defaults
    #: and under the command line (keys of ``pasta demos`` / ``pasta train <stage>``). The optional stages
    #: ``reset`` and ``select`` run by default only for skills that list them (``{}``: with no settings).
    #: ``{"demos": {"trajopt_iterations": I, "trajopt_steps": T}}`` is also the skill's budget of trajectory
    #: optimisation wherever pasta makes its goals so (``pasta.tasks.step.gbto_budget``)
    training_defaults: ClassVar[Mapping[str, Mapping[str, Any]]] = {}
    #: the hooks that making demonstrations needs (see :meth:`has_expert`)
    DEMO_HOOKS: ClassVar[tuple[str, ...]] = ("demo_scene", "sample_expert_params", "expert_approach_pose", "expert")
    #: the hooks that demonstrations by trajectory optimisation need instead of a scripted expert (:meth:`has_gbto`)
    GBTO_HOOKS: ClassVar[tuple[str, ...]] = ("demo_scene", "demo_target")

    def __init__(self, config: Any = None) -> None:
        if not isinstance(getattr(type(self), "spec", None), SkillSpec):
            raise PluginValidationError(f"{type(self).__name__} must define a class attribute `spec: SkillSpec`")
        self.config = config
        self.feasibility_model: Any = None
        self.policy_model: Any = None

    # -- identity ----------------------------------------------------------------------------
    @property
    def name(self) -> str:
        return self.spec.name

    @property
    def n_in(self) -> int:
        return self.spec.n_in

    @property
    def n_out(self) -> int:
        return self.spec.n_out

    @property
    def tool(self) -> str:
        return self.spec.tool

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.name}: {self.n_in} -> {self.n_out}, tool={self.tool})"

    # -- learned components -------------------------------------------------------------------
    @property
    def output_box(self) -> tuple[tuple[float, float, float], tuple[float, float, float]] | None:
        """``(low, high)``: the centroid box of the entities this skill produced in the training data of
        its attached feasibility network (its ``output_box`` attribute; ``None``: none recorded). The
        planner draws and clamps the sub-goal centroids of this skill's steps at this box's heights and,
        on the table plane, in its union with the encoder's box (else in the encoder's;
        :func:`pasta.planning.batch.centroid_box`): a skill that sets dough down on a raised board
        produces centroids that the encoder's training pieces, all on the floor, never had, and its
        network is not to be trusted at heights it never saw."""
        box = getattr(self.feasibility_model, "output_box", None)
        return None if box is None else (tuple(box[0]), tuple(box[1]))

    def attach_feasibility(self, model: Any) -> None:
        """Attach a feasibility network: a callable ``(U_in (B, N, D), U_out (B, M, D)) -> (B,)``."""
        self.feasibility_model = model

    def attach_policy(self, model: Any) -> None:
        """Attach a learned policy: an object whose ``controller(skill)`` returns a :class:`Controller`."""
        self.policy_model = model

    def feasibility(self, u_in: torch.Tensor, u_out: torch.Tensor) -> torch.Tensor:
        """Probability that the skill turns entities ``u_in`` into ``u_out``.

        Args:
            u_in: ``(B, N, D)`` latents of the consumed entities, ``N = n_in``.
            u_out: ``(B, M, D)`` latents of the produced entities, ``M = n_out``.

        Returns:
            ``(B,)`` values in ``[0, 1]``.
        """
        self._check_tuple(u_in, u_out)
        if self.feasibility_model is None:
            raise self._missing("feasibility predictor", "train one with `pasta train feasibility skill=NAME`")
        return self.feasibility_model(u_in, u_out)

    def log_feasibility(self, u_in: torch.Tensor, u_out: torch.Tensor) -> torch.Tensor:
        """``(B,)`` log of :meth:`feasibility`, from the model's logits when it has ``logits(u_in, u_out)``.

        Planners optimise this: ``log sigmoid(logit)`` keeps a useful gradient where the probability has
        saturated at 0, which a product of probabilities does not.
        """
        import torch

        logits = getattr(self.feasibility_model, "logits", None)
        if callable(logits):
            self._check_tuple(u_in, u_out)
            return torch.nn.functional.logsigmoid(logits(u_in, u_out))
        return self.feasibility(u_in, u_out).clamp(min=1e-30).log()

    # -- acting in the simulator (filled by skill plugins) ------------------------------------
    def approach_pose(self, piece: np.ndarray, goal: np.ndarray) -> ToolPose:
        """Where to place the tool before executing on ``piece (P, 3)`` towards ``goal (G, 3)``."""
        raise self._missing("approach pose", "the skill plugin does not define `approach_pose`")

    def park_pose(self) -> ToolPose:
        """Where the tool waits while other skills run."""
        raise self._missing("parking pose", "the skill plugin does not define `park_pose`")

    def sample_expert_params(self, piece: np.ndarray, rng: np.random.Generator) -> dict[str, float]:
        """Random parameters of the scripted expert for ``piece (P, 3)`` (cut position, push target...)."""
        raise self._missing("scripted expert", "the skill plugin does not define `sample_expert_params`")

    def expert(self, params: dict[str, float]) -> Controller:
        """Scripted expert with explicit parameters, used for demonstrations and goals."""
        raise self._missing("scripted expert", "the skill plugin does not define `expert`")

    def expert_approach_pose(self, piece: np.ndarray, params: dict[str, float], scene: np.ndarray | None = None) -> ToolPose:
        """Where the expert with ``params`` starts on ``piece (P, 3)``; ``scene (S, 3)``: all dough, to avoid."""
        raise self._missing("scripted expert", "the skill plugin does not define `expert_approach_pose`")

    def unfinished(self, piece: np.ndarray, goal: np.ndarray) -> bool:
        """Whether ``piece (P, 3)`` visibly still needs this skill to become ``goal (G, 3)`` although it lies
        within :attr:`at_goal` of it: the step is then started, and such a demonstration is kept. Chamfer
        misses what a skill's own measure sees (a 6 cm cube lies within 1e-3 of the 1.8 cm sheet a roll
        makes of it). Default: ``False`` (the distance decides)."""
        return False

    # -- learned reset pose (optional; `pasta.policy.reset`) ------------------------------------------
    def reset_target(self, tool_x: float) -> tuple[float, ...]:
        """What a learned reset pose regresses for a demonstration whose tool started at ``tool_x``:
        quantities the goal shows directly. The first is an ``x`` coordinate (learned as an offset from
        the piece centroid), any others are unitless. Default: ``(tool_x,)``. Override it (with its
        inverse :meth:`reset_tool_x`) when the tool's effect is not where the tool is, e.g. the cut: the
        dough parts up to a grid cell away from the knife, depending on where the knife lies in its
        cell, so the regressor learns the plane where the dough parts and that phase, and the skill
        places the knife."""
        return (float(tool_x),)

    def reset_tool_x(self, target: Sequence[float]) -> float:
        """The tool's start ``x`` for a regressed :meth:`reset_target` (its inverse; default: ``target[0]``)."""
        return float(target[0])

    # -- demonstrations (filled by skill plugins; used by `pasta demos`, the pipeline and evaluation) --
    def demo_scene(self, rng: np.random.Generator, floor_y: float, variant: str = "default") -> list[SceneBox]:
        """The dough a demonstration starts from: ``n_in`` boxes ``[(centre, size), ...]`` resting on ``floor_y``.

        Draw every random number from ``rng`` (demo ``i`` is reproducible from its seed). The expert then
        acts on all of the scene's dough as its piece (``P`` points of the ``n_in`` boxes together).
        ``variant``: ``"default"`` or a key of :attr:`demo_variants`. Particles are split between the
        boxes in proportion to their volumes.
        """
        raise self._missing("demonstration scene", "the skill plugin does not define `demo_scene`")

    def demo_tools(self, variant: str = "default") -> dict[str, ToolPose]:
        """Static tools a demonstration scene of ``variant`` places besides the skill's own tool,
        ``{tool name: pose}`` (e.g. the raised board a lift sets the dough on). Placed after the dough is
        loaded, before it settles. Default: none. (An override without the ``variant`` argument is called
        without it.)"""
        return {}

    def demo_target(self, dough: np.ndarray, rng: np.random.Generator, variant: str = "default") -> np.ndarray:
        """What a demonstration made by gradient-based trajectory optimisation (``pasta demos expert=trajopt``,
        for a skill without a scripted expert) should leave: the dough ``(G, 3)`` after the step, for the settled
        demonstration scene ``dough (P, 3)`` (all its pieces). Draw every random number from ``rng``. The tool
        starts at :meth:`approach_pose` ``(dough, target)``; the optimiser then looks for the actions whose
        result is closest to the target (a Sinkhorn divergence), so a target the tool can reach in the skill's
        way (a piece moved, split or flattened as the tool would) makes demonstrations of that skill."""
        raise self._missing("demonstration target", "the skill plugin does not define `demo_target`")

    @classmethod
    def missing_gbto_hooks(cls) -> list[str]:
        """The hooks of :attr:`GBTO_HOOKS` this class does not override (empty: trajectory optimisation can make
        its demonstrations)."""
        return [h for h in cls.GBTO_HOOKS if getattr(cls, h) is getattr(Skill, h)]

    @classmethod
    def has_gbto(cls) -> bool:
        """Whether demonstrations can be made by trajectory optimisation: the class overrides ``demo_scene`` and
        ``demo_target`` (and :meth:`approach_pose`, which every skill that runs has)."""
        return not cls.missing_gbto_hooks()

    @classmethod
    def missing_demo_hooks(cls) -> list[str]:
        """The hooks of :attr:`DEMO_HOOKS` this class does not override (empty: it can make demonstrations)."""
        return [h for h in cls.DEMO_HOOKS if getattr(cls, h) is getattr(Skill, h)]

    @classmethod
    def goals_by_trajopt(cls) -> bool:
        """Whether pasta makes this skill's goals (task steps, evaluation configs) by trajectory optimisation:
        it has no scripted expert but can make demonstrations so (:meth:`has_gbto`)."""
        return not cls.has_expert() and cls.has_gbto()

    @classmethod
    def has_controller(cls) -> bool:
        """Whether the class defines a heuristic controller (overrides :meth:`controller`)."""
        return cls.controller is not Skill.controller

    @classmethod
    def has_expert(cls) -> bool:
        """Whether the class overrides every hook demonstrations need: ``demo_scene``, ``sample_expert_params``,
        ``expert_approach_pose`` and ``expert``. ``pasta demos`` and ``pasta pipeline`` take such skills."""
        return not cls.missing_demo_hooks()

    def controller(self) -> Controller:
        """Heuristic controller working from point clouds only (observed piece and sub-goal)."""
        raise self._missing("heuristic controller", "the skill plugin does not define `controller`")

    def policy(self) -> Controller:
        """Learned point-cloud policy: the attached policy model's ``controller(skill)``."""
        if self.policy_model is None:
            raise self._missing("learned policy", "train one with `pasta train policy skill=NAME`")
        return self.policy_model.controller(self)

    # -- helpers ------------------------------------------------------------------------------
    def _missing(self, what: str, fix: str) -> MissingComponentError:
        return MissingComponentError(f"skill '{self.name}' has no {what}: {fix.replace('NAME', self.name)}")

    def _check_tuple(self, u_in: Any, u_out: Any) -> None:
        s_in, s_out = tuple(getattr(u_in, "shape", ())), tuple(getattr(u_out, "shape", ()))
        if len(s_in) != 3 or len(s_out) != 3 or s_in[0] != s_out[0] or s_in[2] != s_out[2]:
            raise InputError(
                f"skill '{self.name}': feasibility expects U_in (B, {self.n_in}, D) and U_out (B, {self.n_out}, D), "
                f"got {s_in} and {s_out}"
            )
        if s_in[1] != self.n_in or s_out[1] != self.n_out:
            raise InputError(
                f"skill '{self.name}' consumes {self.n_in} and produces {self.n_out} entities, "
                f"got U_in with {s_in[1]} and U_out with {s_out[1]}"
            )
