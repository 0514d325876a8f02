"""Every setting of a run, in one structured config: what ``pasta config`` prints and ``key=value`` sets.

``pasta plan``, ``pasta run`` and ``pasta eval`` read the same :class:`RunConfig`:

- top level: ``seed``, ``device``, ``threads``, ``models``, ``method``, ``horizon``, ``skills``, ``skeleton``;
- groups, each a registered plugin's own settings, swapped in by name: ``planner=NAME``, ``encoder=NAME``,
  ``cost_model=NAME`` and ``task=NAME`` (the task's settings, ``task.distractors=4``);
- ``perception.*`` (:class:`PerceptionConfig`), ``check.*`` (:class:`CheckConfig`), ``execute.*``
  (:class:`ExecuteConfig`), ``sim.*`` (:class:`pasta.sim.SimConfig`, with ``sim.tool_friction.<tool>``);
- ``skill.<name>.*``: every registered skill's own settings (its plugin's config dataclass).

Every default is the setting behind the shipped results; each section's docstring says which result
justifies it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from pasta.core.errors import ConfigError
from pasta.sim.config import SimConfig

__all__ = ["CONTROLLERS", "CheckConfig", "ExecuteConfig", "GOAL_MODES", "METHODS", "PerceptionConfig", "RunConfig", "TrajOptConfig"]

#: ``method``: PASTA (entity latents, the configured planner), the Flat 3D baseline (the whole scene as one
#: latent, ``MODELS/flat``), the oracle (the task's ground-truth chain with the heuristic controllers), or Traj-Opt
#: (gradient descent on the ground-truth chain's actions through the simulator, :class:`TrajOptConfig`)
METHODS = ("pasta", "flat", "oracle", "trajopt")
#: ``execute.controller``: a skill's heuristic point-cloud controller, or its learned policy
CONTROLLERS = ("heuristic", "learned")
#: ``execute.goal``: how a step's goal pieces are made (:mod:`pasta.execute.goals`)
GOAL_MODES = ("observed", "decoded")
LOOPS = ("open", "closed")


@dataclass
class PerceptionConfig:
    """How a dough cloud becomes entities (``perception.<key>=``). The defaults are the paper's planning and
    execution values (PASTA's release).

    Attributes:
        num_points: points per entity after decomposition, and per decoded sub-goal entity (paper: 1,000).
        min_points: DBSCAN clusters smaller than this are noise and join their nearest piece (paper: 50
            at planning and execution).
        eps: DBSCAN neighbourhood radius in metres (paper: 0.03).
        min_samples: DBSCAN core-point neighbour count (paper: 6).
        max_points: a cloud with more points is voxel-downsampled to at most this many before
            decomposition (DBSCAN's memory grows with the square of a dense cloud's size: 1e5 points took
            6 GB; 10,000 leaves the usual 1,000-5,000-point clouds untouched).
        unchanged_threshold: an observed entity within this Chamfer distance of a goal entity is that goal
            piece already: the planner never attends it and matches it to that piece in the set cost
            (paper: 5e-4; crs with 6 distractors plans the right skeleton on 10/10 configs with it, 2/5
            without, docs/planning.md); 0 disables it.
    """

    num_points: int = 1000
    min_points: int = 50
    eps: float = 0.03
    min_samples: int = 6
    max_points: int = 10_000
    unchanged_threshold: float = 5e-4

    def __post_init__(self) -> None:
        from pasta.config.validate import check_int, check_number

        check_int(self.num_points, "perception.num_points", low=16, high=10_000)
        check_int(self.min_points, "perception.min_points", low=1)
        check_number(self.eps, "perception.eps", low=0.0, low_open=True, high=1.0)
        check_int(self.min_samples, "perception.min_samples", low=1, high=10_000)
        check_int(self.max_points, "perception.max_points", low=1)
        check_number(self.unchanged_threshold, "perception.unchanged_threshold", low=0.0)
        if self.max_points < self.min_points:
            raise ConfigError(f"perception.max_points={self.max_points}: must be >= perception.min_points "
                              f"({self.min_points}), or no downsampled cloud could hold one entity")

    def decompose_kwargs(self) -> dict[str, Any]:
        """The keyword arguments of :func:`pasta.core.decompose.decompose_labels`."""
        return {"eps": float(self.eps), "min_samples": int(self.min_samples), "min_points": int(self.min_points)}


@dataclass
class CheckConfig:
    """The checks of a plan against the models' training distribution (``check.<key>=``; docs/real_world.md).

    Attributes:
        box_margin: an observed or goal entity whose centroid lies more than this (metres) outside every box
            of training centroids is refused (the planner clamps sub-goals into those boxes, so such a
            plan would be silently wrong).
        min_feasibility: a plan step predicted below this is flagged unreachable (``pasta plan`` exits 3).
        max_cost: a final set cost above this (Chamfer) is flagged unreachable.
        max_z: a latent with ``|z|`` above this (Mahalanobis distance under the prior N(0, I)) is flagged out
            of distribution (a warning only): entities of the validation seeds 2000-2002 (crs,
            cut_rearrange) reach 2.94 (full clouds) and 3.28 (camera views).
        volume_ratio: a goal whose dough volume (summed convex hulls of its pieces,
            :mod:`pasta.perception.volume`) is more than this many times the observation's, or less than its
            inverse, is refused as unreachable before planning (exit 3). Chosen on the validation configs
            (seeds 2000-2019) of every task: goal/observation ratios 0.96-1.78 on full clouds, 1.01-1.20 on
            camera views of crs and cut_rearrange (``preprocess=camera``); test configs 0.96-1.77.
    """

    box_margin: float = 0.01
    min_feasibility: float = 0.5
    max_cost: float = 0.01
    max_z: float = 4.0
    volume_ratio: float = 2.5

    def __post_init__(self) -> None:
        from pasta.config.validate import check_number

        check_number(self.box_margin, "check.box_margin", low=0.0, high=1.0)
        check_number(self.min_feasibility, "check.min_feasibility", low=0.0, high=1.0)
        check_number(self.max_cost, "check.max_cost", low=0.0, low_open=True)
        check_number(self.max_z, "check.max_z", low=0.0, low_open=True)
        check_number(self.volume_ratio, "check.volume_ratio", low=1.0, low_open=True)


@dataclass
class ExecuteConfig:
    """Settings of plan execution (``execute.<key>=``; :func:`pasta.execute.execute_plan`).

    Attributes:
        controller: ``heuristic`` (each skill's point-cloud controller) or ``learned`` (its trained policy).
        goal: ``observed``: a step's decoded sub-goal, corrected by the task's goal where the plan makes that
            exact (:mod:`pasta.execute.goals`); ``decoded``: the plain decodings, as in the paper (heuristic
            controllers, test configs: cut_rearrange 0.930 / 90 % observed against 0.835 / 75 % with
            decodings, crs 0.937 / 100 % against 0.829 / 60 %).
        idle_steps: zero-action env steps after each skill step, so the dough settles (paper: 10).
        retries: a step that visibly failed (it hit the skill's step limit, or fewer pieces are observed
            than it makes: a cut whose bottom layer still joins the halves) runs again from the new
            observation, at most this many times (crs seeds 1002 and 1013: 0.48 and -1.72 without a
            retry, 0.845 and 0.854 with one).
        regress_rise: a learned step ends once its piece, having come at least halfway to the goal, stays
            more than this fraction of its best Chamfer distance away for 3 env steps (a learned push whose
            done head stays low pushes on past its goal; docs/policies.md).
        regress_near: a learned step whose piece starts within this Chamfer distance of its goal is ended
            as soon as the piece moves away (a learned roll of a piece that is flat already spreads it on;
            crs_twice validation: such second rolls started 2e-4 to 9e-4 from their goal, first rolls
            9e-4 to 3.3e-3).
        overrun: a learned policy stopped only by its own step cap runs on for at most this many env steps
            while each brings its piece closer than ever (crs_twice's first cut carries its piece further
            than any demonstration did: learned crs_twice 20 % -> 35 % on validation).
        loop: ``open``: execute the plan as planned (PASTA); ``closed``: after each step, test whether the rest
            of the plan fits what is observed (:func:`pasta.execute.loop.plan_fit`) and re-plan the remaining
            steps when it does not (docs/policies.md, "Closed loop").
        fit_distance: the closed loop's tolerance: a piece further than this (metres) from the centroid the
            plan expects makes the plan not fit.
    """

    controller: str = "heuristic"
    goal: str = "observed"
    idle_steps: int = 10
    retries: int = 1
    regress_rise: float = 0.5
    regress_near: float = 0.001
    overrun: int = 40
    loop: str = "open"
    fit_distance: float = 0.03

    def __post_init__(self) -> None:
        from pasta.config.validate import check_choice, check_int, check_number

        check_choice(self.controller, "execute.controller", CONTROLLERS)
        check_choice(self.loop, "execute.loop", LOOPS)
        check_number(self.fit_distance, "execute.fit_distance", low=0.0, low_open=True, high=1.0)
        check_choice(self.goal, "execute.goal", GOAL_MODES)
        check_int(self.idle_steps, "execute.idle_steps", low=0)
        check_int(self.retries, "execute.retries", low=0)
        check_number(self.regress_rise, "execute.regress_rise", low=0.0, low_open=True)
        check_number(self.regress_near, "execute.regress_near", low=0.0)
        check_int(self.overrun, "execute.overrun", low=0)


@dataclass
class TrajOptConfig:
    """The Traj-Opt baseline (``method=trajopt``, ``trajopt.<key>=``; :mod:`pasta.execute.trajopt`): Adam on the
    whole action sequence of the task's ground-truth tool chain, through the differentiable simulator.

    Attributes:
        iterations: gradient steps per episode (each a rollout and its backward pass: ~0.2 s per env step at
            5,000 particles on 2 cores, so ~30 s an iteration for a 3-skill chain). The paper ran 200; the
            shipped rows ran 10 (docs/simulator.md, "Traj-Opt").
        lr: Adam's learning rate on actions in [-1, 1] (paper: 0.01-0.02 with 200 iterations).
        steps: env steps per skill of the chain (paper: 50).
        points: particles in the loss, drawn once per episode (paper: 500).
        blur: the Sinkhorn loss's entropic blur in metres (:func:`pasta.sim.grad.sinkhorn`'s ``eps`` with ``p=1``, the
            tasks' EMD; paper: geomloss, p = 1, blur 0.001).
        contact: weight of the contact term (the squared distance from the active tool's centre to the nearest
            loss particle, summed over its steps), which pulls a tool that touches nothing toward the dough
            (paper: 1e-3).
    """

    iterations: int = 10
    lr: float = 0.1
    steps: int = 50
    points: int = 500
    blur: float = 1e-3
    contact: float = 1e-3

    def __post_init__(self) -> None:
        from pasta.config.validate import check_int, check_number

        check_int(self.iterations, "trajopt.iterations", low=0, high=100_000)
        check_number(self.lr, "trajopt.lr", low=0.0, low_open=True, high=10.0)
        check_int(self.steps, "trajopt.steps", low=1, high=10_000)
        check_int(self.points, "trajopt.points", low=8, high=1_000_000)
        check_number(self.blur, "trajopt.blur", low=0.0, low_open=True)
        check_number(self.contact, "trajopt.contact", low=0.0)


@dataclass
class RunConfig:
    """Root of the run configuration (see the module docstring).

    Attributes:
        seed: the run's seed (planning draws; ``pasta run`` also takes it as the task instance).
        device: torch device of the learned policies (``cpu``, ``cuda``, ``cuda:N``).
        threads: torch CPU threads (0: torch's default). 1: crs planning took 5.6 s with 1 thread and 126 s
            with 2 on a 2-core machine that also ran a training job.
        models: root of trained weights (``pasta train ... out=DIR``); empty: the shipped ones.
        method: see :data:`METHODS`.
        horizon: planning horizon, 1 to :data:`pasta.config.MAX_HORIZON` (10; the skeleton enumeration grows
            with K**H); not given (``null``): the task's (3 for ``pasta plan``), or the length of a given
            ``skeleton``. ``horizon=0`` and ``horizon=`` are refused: omit the key for the task's horizon.
        skills: comma-separated skills to plan with; empty: every registered skill with trained weights.
        skeleton: a fixed skill sequence (``cut,push,roll``), ``task`` (the task's ground-truth chain), or
            empty (the planner searches).
        disturb: a disturbance after the first executed step (:data:`pasta.sim.disturb.DISTURBANCES`: shift,
            split, merge, lump, noise), drawn from ``seed``; empty: none.
    """

    seed: int = 0
    device: str = "cpu"
    threads: int = 1
    models: str = ""
    method: str = "pasta"
    horizon: int | None = None
    skills: str = ""
    skeleton: str = ""
    disturb: str = ""
    planner: Any = None
    encoder: Any = None
    cost_model: Any = None
    task: Any = None
    perception: PerceptionConfig = field(default_factory=PerceptionConfig)
    check: CheckConfig = field(default_factory=CheckConfig)
    execute: ExecuteConfig = field(default_factory=ExecuteConfig)
    trajopt: TrajOptConfig = field(default_factory=TrajOptConfig)
    sim: SimConfig = field(default_factory=SimConfig)
    skill: Any = None
