"""Simulator configuration: one plain dataclass, omegaconf-compatible (only int/float/str/bool fields)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from typing import Any

from pasta.core.errors import ConfigError

#: Parameters that live in Taichi scalar fields and can change at run time without a recompile
#: (``Simulator.set_params``).
RUNTIME_PARAMS = (
    "dt",
    "E",
    "nu",
    "yield_stress",
    "gravity",
    "ground_friction",
    "spread_friction",
    "spread_x_min",
    "spread_x_max",
    "softness",
)


@dataclass
class SimConfig:
    """Everything the simulator needs. Units: the workspace is the unit cube, y is up, time in seconds.

    Structural fields (changing them means new Taichi fields, hence new kernels): ``n_grid``,
    ``max_particles``, ``arch``, ``cpu_threads``, ``fast_math`` (``arch`` and ``fast_math``: one value per
    process). Everything in :data:`RUNTIME_PARAMS` is a runtime
    scalar and can also be changed later with ``Simulator.set_params``; ``substeps``,
    ``n_particles``, ``obs_points`` and ``seed`` are plain Python values.

    ``tool_friction`` maps a tool name to its Coulomb friction, overriding the tool's
    ``ToolSpec.friction`` (``sim.tool_friction.knife=0.2``); also a runtime value
    (``Simulator.set_params(knife_friction=0.2)``).

    Defaults: grid 64^3 (dx = 0.0156: a 0.05 knife spans 3.2 cells, a 0.08 dough 5.1 cells),
    dt = 1e-4 (CFL ~0.46 for the P-wave speed of E = 5e3, rho = 1), 20 substeps per env step
    (2 ms of simulated time per env step).
    """

    # --- structure -----------------------------------------------------------------------------
    n_grid: int = 64
    max_particles: int = 10000
    arch: str = "cpu"  # "cpu" | "cuda" | "gpu" | "vulkan" | "metal"
    cpu_threads: int = 2  # 0 = let Taichi decide
    # Taichi's fast_math (one value per process). Off keeps IEEE float semantics, so instances reproduce across
    # machines; on is ~23% faster and was used for the results before issue 21 (docs/simulator.md, Reproducibility)
    fast_math: bool = False
    # --- time ----------------------------------------------------------------------------------
    dt: float = 1e-4
    substeps: int = 20
    # --- material (fixed-corotated + von Mises on Hencky strain) --------------------------------
    E: float = 5e3
    nu: float = 0.15
    yield_stress: float = 150.0
    # --- world ---------------------------------------------------------------------------------
    gravity: float = -300.0  # y acceleration (large, as in PlasticineLab: quasi-static tool contact)
    ground_friction: float = 0.5  # Coulomb floor friction outside the spreading area
    spread_friction: float = 2.0  # Coulomb floor friction inside the spreading area
    spread_x_min: float = 0.22
    spread_x_max: float = 0.32
    # --- tools ---------------------------------------------------------------------------------
    softness: float = 666.0  # contact band: influence exp(-softness * sdf) > 0.1
    tool_friction: dict[str, float] = field(default_factory=dict)  # tool name -> friction (over ToolSpec.friction)
    # --- scenes and observations --------------------------------------------------------------
    n_particles: int = 5000  # default particle count for scene helpers (1..max_particles)
    obs_points: int = 1000  # size of the observed dough subset
    seed: int = 0

    def __post_init__(self) -> None:
        def bad(name: str, why: str) -> ConfigError:
            return ConfigError(f"sim.{name}={getattr(self, name)!r}: {why}")

        for f in fields(self):
            val = getattr(self, f.name)
            if f.name == "tool_friction":
                self.tool_friction = check_tool_friction(val)
                continue
            if f.type in ("int", int) and (isinstance(val, bool) or not isinstance(val, int)):
                raise bad(f.name, "must be an int")
            if f.type in ("float", float):
                if isinstance(val, bool) or not isinstance(val, (int, float)):
                    raise bad(f.name, "must be a number")
                if not math.isfinite(float(val)):
                    raise bad(f.name, "must be finite")
                object.__setattr__(self, f.name, float(val))
        if not 16 <= self.n_grid <= 512:
            raise bad("n_grid", "must be in [16, 512] (64 recommended)")
        if not 1 <= self.max_particles <= 10_000_000:
            raise bad("max_particles", "must be in [1, 1e7]")
        if not 1 <= self.n_particles <= self.max_particles:
            raise bad("n_particles", f"must be in [1, max_particles={self.max_particles}]")
        if not 1 <= self.obs_points <= 10_000_000:
            raise bad("obs_points", "must be in [1, 1e7]")
        if not isinstance(self.fast_math, bool):
            raise bad("fast_math", "must be true or false")
        if self.arch not in ("cpu", "cuda", "gpu", "vulkan", "metal"):
            raise bad("arch", "must be one of cpu, cuda, gpu, vulkan, metal")
        if self.cpu_threads < 0:
            raise bad("cpu_threads", "must be >= 0 (0 = Taichi's default)")
        if self.substeps < 1:
            raise bad("substeps", "must be >= 1")
        check_params({k: getattr(self, k) for k in RUNTIME_PARAMS}, prefix="sim.")

    @property
    def dx(self) -> float:
        return 1.0 / self.n_grid

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> SimConfig:
        """Build from a plain dict (a run's ``sim_config.json``) that names every setting. A dict of an older
        format (per-tool ``<tool>_friction`` keys, no ``fast_math``) is refused with one error naming it."""
        d = dict(d)
        known = {f.name for f in fields(cls)}
        legacy = sorted(k for k in d if k not in known and k.endswith("_friction")) + (
            [] if "fast_math" in d else ["no fast_math"])
        if legacy:
            raise ConfigError(f"simulator settings of an older format ({', '.join(legacy)}: written before tool "
                              "frictions were one mapping and fast_math was recorded); replay the run with the pasta "
                              "that wrote it")
        unknown = sorted(set(d) - known)
        if unknown:
            raise ConfigError(f"unknown simulator settings {unknown}; known: {', '.join(sorted(known))}")
        return cls(**d)


def check_tool_friction(val: Any) -> dict[str, float]:
    """A validated ``{tool name: friction >= 0}`` copy (also accepts an omegaconf mapping)."""
    if val is None:
        return {}
    try:
        items = list(val.items())
    except AttributeError:
        raise ConfigError(f"sim.tool_friction={val!r}: must be a mapping tool name -> friction") from None
    out = {}
    for k, v in items:
        if not isinstance(k, str) or not k:
            raise ConfigError(f"sim.tool_friction: key {k!r} must be a tool name")
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(float(v)) or float(v) < 0:
            raise ConfigError(f"sim.tool_friction.{k}={v!r}: must be a finite number >= 0")
        out[k] = float(v)
    return out


def check_params(p: dict, prefix: str = "") -> None:
    """Validate runtime parameters; raise ConfigError naming the first bad one."""
    for k, v in p.items():
        if k not in RUNTIME_PARAMS:
            raise ConfigError(f"unknown simulator parameter '{k}'; known: {', '.join(RUNTIME_PARAMS)}")
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(float(v)):
            raise ConfigError(f"{prefix}{k}={v!r}: must be a finite number")
    rules = {
        "dt": lambda v: v > 0,
        "E": lambda v: v > 0,
        "nu": lambda v: -1.0 < v < 0.5,
        "yield_stress": lambda v: v > 0,
        "ground_friction": lambda v: v >= 0,
        "spread_friction": lambda v: v >= 0,
        "softness": lambda v: v >= 0,
    }
    what = {
        "nu": "must be in (-1, 0.5)",
    }
    for k, v in p.items():
        rule = rules.get(k)
        if rule is not None and not rule(float(v)):
            raise ConfigError(f"{prefix}{k}={v!r}: {what.get(k, 'must be > 0' if k in ('dt', 'E', 'yield_stress') else 'must be >= 0')}")
