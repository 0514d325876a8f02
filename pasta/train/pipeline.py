"""``pasta pipeline``: demonstrations and every learned module in one resumable run.

Units run in this order, each one a ``pasta demos`` or ``pasta train`` call, or for the last two stages
``python -m pasta.train.reset`` / ``python -m pasta.train.select``::

    demos/<skill> (+ demos/<skill>-<variant>) -> vae -> feasibility/<skill> -> cost -> policy/<skill>
        -> reset/<skill> -> select/<skill>

The skills are every registered skill that can make demonstrations (:func:`pasta.demos.demo_skills`)
unless ``skills=`` names some. Each skill's plugin brings its own settings
(:attr:`pasta.core.Skill.training_defaults`, applied over :data:`STAGE_DEFAULTS`) and the scene variants
whose demonstrations the pipeline adds after the default ones (:attr:`pasta.core.DemoVariant.pipeline_demos`,
unit ``demos/<skill>-<variant>``, e.g. push's ``demos/push-wide``).

``reset/<skill>`` trains the learned reset (start) pose of a policy (:mod:`pasta.train.reset`; by default
for the skills whose ``training_defaults`` list ``reset``, ``reset_skills=``) into
``OUT/policy/<skill>/reset.*``; ``select/<skill>`` chooses the policy's stopping rule on the validation
configs (seed 2000) and writes it into its ``model.json`` (:mod:`pasta.train.select`; by default for the
skills that list ``select``, ``select_skills=``), with the per-config results in
``OUT/policy/<skill>/select.json``. Both run after every policy unit, so a rule is chosen with the
skill's reset pose in place.

Resuming. ``OUT/pipeline.json`` records, per unit, the settings it was (or is being) produced with: the
resolved trainer configuration (less ``progress``, ``threads``, ``resume`` and ``workers``, which do
not change the result), the dataset (absolute path and demonstrations per skill) and, for
feasibility and cost, a digest of the VAE weights they encode with. A training unit is *done* when its
``metrics.json`` exists and its record holds the same settings; done units are skipped. A unit whose
record holds the same settings but which has no ``metrics.json`` was interrupted: the training loop
resumes it from its ``last.*`` checkpoint (a ``reset`` unit from its ``reset_last.*``; a ``select`` unit
resumes at the first config it had not scored). ``reset`` and ``select`` units write into the policy's
directory but have their own done files (``reset_metrics.json``, ``select.json``); a ``select`` unit's
settings include digests of the policy and reset weights it scored, so a retrained policy reselects, and
it is only done while ``model.json`` still holds the rule it chose. A unit with no record or other settings starts afresh (its
``last.*`` and ``metrics.json`` are removed first, so a stale checkpoint is never continued). A demos
unit is done when its record matches and every file exists; otherwise ``pasta demos`` fills in the
missing files (it never rewrites existing ones).

Backends. ``backend=ray`` (with ``ray.address=``, :class:`pasta.distributed.BackendConfig`) makes the
demos units' demonstrations as Ray tasks (``workers``: the most in flight); the training units run in
this process, one after the other (each depends on the last, or trains on every skill's data). The
backend is not part of a unit's settings: switching it never reruns a unit. See docs/scaling.md.

Every unit's configuration is built up front with the trainers' own config builders, so a typo in
``<stage>.<key>=value`` fails with their "did you mean" message before any work starts.
"""

from __future__ import annotations

import hashlib
import json
import os
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from pasta.core.errors import ConfigError, did_you_mean

__all__ = ["PipelineConfig", "Unit", "UnitResult", "STAGES", "STAGE_DEFAULTS", "FIGURES", "parse_arguments",
           "plan", "run_pipeline", "skill_defaults", "summary_table"]

FORMAT = "pasta-pipeline/1"
RECORD = "pipeline.json"
#: stage order (the order units run in)
STAGES = ("demos", "vae", "feasibility", "cost", "policy", "reset", "select")
#: stages with one unit per skill
PER_SKILL = ("demos", "feasibility", "policy", "reset", "select")
#: stages that only run for some skills: the pipeline argument that names them
SKILL_SUBSETS = {"reset": "reset_skills", "select": "select_skills"}
#: stages whose units work on the trained policy of their skill (they write into OUT/policy/<skill>)
ON_POLICY = ("reset", "select")
#: stages whose units encode with the trained VAE
USES_VAE = ("feasibility", "cost")
#: pipeline defaults per stage: sized for a 2-core CPU, the settings the shipped models were trained with
STAGE_DEFAULTS: dict[str, dict[str, Any]] = {
    "demos": {},
    "vae": {"epochs": 11, "stride": 5, "threads": 1},
    "feasibility": {"threads": 1},
    "cost": {"stride": 5, "threads": 1},
    "policy": {"epochs": 40, "steps_per_epoch": 50, "threads": 1},
    "reset": {"threads": 1},
    "select": {"n": 20, "seed": 2000, "write": True, "threads": 1},
}
#: value of ``skills``, ``reset_skills`` and ``select_skills`` that means "what the skill plugins ask for"
AUTO = "auto"
#: the held-out figure reported for each stage (a key of its metrics.json)
FIGURES = {"vae": "heldout_chamfer_mean", "feasibility": "heldout_auc_hard", "cost": "heldout_spearman",
           "policy": "heldout_action", "reset": "heldout_mae_m", "select": "mean_ni"}
#: the file whose presence (with a matching record) marks a unit of these stages done, in its directory
DONE_FILES = {"reset": "reset_metrics.json", "select": "select.json"}
#: what a fresh start removes from a unit's directory, per stage (default: the training loop's files)
FRESH_FILES = {"reset": ("reset_metrics.json", "reset_last.safetensors", "reset_last.json"),
               "select": ("select.json", "select.partial.jsonl")}
#: keys the pipeline sets itself, per stage, and where to set them instead
_FLAT = "`pasta train <module> flat=true` for the Flat 3D baseline (the pipeline trains the entity models)"
RESERVED = {"demos": {"skill": "skills=", "out": "data="}, "feasibility": {"skill": "skills=", "flat": _FLAT},
            "policy": {"skill": "skills="}, "vae": {"flat": _FLAT, "subdir": _FLAT}, "cost": {"flat": _FLAT},
            "reset": {"skill": "skills= and reset_skills=", "data": "data=", "out": "out="},
            "select": {"skill": "skills= and select_skills=", "models": "out=", "out": "out="}}
#: settings that do not change what a unit produces; changing them does not rerun it
IGNORED = ("progress", "threads", "resume", "workers")


@dataclass
class PipelineConfig:
    """The pipeline's own ``key=value`` arguments (everything without a ``<stage>.`` prefix).

    Attributes:
        data: dataset directory (written by the demos stage, read by the others).
        out: models root; also holds ``pipeline.json``.
        num_demos: demonstrations per skill (``demos.num``).
        variant_demos: demonstrations per scene variant a skill declares for the pipeline
            (:attr:`pasta.core.DemoVariant.pipeline_demos`, e.g. push's 150 ``scene=wide``), added after
            the default ones (unit ``demos/<skill>-<variant>``); -1: each variant's own number; 0: none.
        workers: demo generation processes (``demos.workers``).
        stages: comma-separated stages to run, of demos, vae, feasibility, cost, policy, reset, select.
        skills: comma-separated skills for the per-skill stages (demos, feasibility, policy, reset, select);
            ``auto``: every registered skill that can make demonstrations.
        reset_skills: the skills of ``skills`` whose policy gets a learned reset pose (stage ``reset``);
            ``auto``: those whose plugin lists ``reset`` in its ``training_defaults``; empty: none.
        select_skills: the skills of ``skills`` whose policy's stopping rule is chosen on validation
            configs (stage ``select``; the others keep the default rule); ``auto``: those whose plugin
            lists ``select``; empty: none.
        force: rerun every selected unit, done or not (demonstrations are never deleted).
        only: comma-separated units or stages to run, e.g. ``feasibility/cut,cost`` (empty: all).
        progress: draw the inner progress bars (stderr).
    """

    data: str = "data/demos"
    out: str = "models"
    num_demos: int = 200
    variant_demos: int = -1
    workers: int = 2
    stages: str = ",".join(STAGES)
    skills: str = AUTO
    reset_skills: str = AUTO
    select_skills: str = AUTO
    force: bool = False
    only: str = ""
    progress: bool = True


@dataclass
class Unit:
    """One step of the pipeline: a demos run of one skill, or one trained module.

    Attributes:
        name: ``stage`` or ``stage/skill``.
        values: the ``key=value`` settings handed to the trainer (defaults and overrides merged).
        configs: the dataclasses those settings build (validated up front; fingerprinted).
        directory: where the unit writes (``DATA/<skill>`` for demos, the module directory otherwise).
    """

    name: str
    stage: str
    skill: str | None
    values: dict[str, Any]
    configs: tuple
    directory: Path


@dataclass
class UnitResult:
    name: str
    status: str  # "ran", "skipped", "failed" or "interrupted"
    wall_s: float = 0.0
    figure: str = ""
    metrics: dict[str, Any] = field(default_factory=dict)


# ---------------------------------------------------------------------------------------------- arguments


def _names(text: str, what: str) -> list[str]:
    names = [n.strip() for n in str(text).split(",") if n.strip()]
    if not names:
        raise ConfigError(f"{what}= names nothing")
    return list(dict.fromkeys(names))


def _known_skills() -> list[str]:
    from pasta.plugins import get_plugins

    return list(get_plugins().skills.names())


def _skill_class(name: str) -> type:
    from pasta.plugins import get_plugins

    return get_plugins().skills.load(name)


def skill_defaults(stage: str, skill: str | None) -> dict[str, Any]:
    """The pipeline settings the plugin of ``skill`` asks for in ``stage`` (its ``training_defaults``)."""
    if not skill:
        return {}
    return dict(_skill_class(skill).training_defaults.get(stage) or {})


def _skills(cfg: PipelineConfig) -> list[str]:
    """``skills=`` as names; ``auto``: the registered skills that can make demonstrations."""
    if str(cfg.skills).strip() == AUTO:
        from pasta.demos import demo_skills

        names = demo_skills()
        if not names:
            raise ConfigError("no registered skill can make demonstrations (none defines demo_scene and an expert); "
                              "name the skills with skills=")
        return names
    names = _names(cfg.skills, "skills")
    _check_names(names, _known_skills(), "skill")
    return names


def _check_names(names: Sequence[str], known: Sequence[str], what: str) -> None:
    for name in names:
        if name not in known:
            raise ConfigError(f"unknown {what} '{name}'{did_you_mean(name, known)}; known {what}s: {', '.join(known)}")


Overrides = dict[tuple[str, str | None], dict[str, Any]]


def parse_arguments(items: Sequence[str] | Mapping[str, Any]) -> tuple[PipelineConfig, Overrides]:
    """Split the arguments into the pipeline's own config and the stage settings.

    Returns:
        ``(config, overrides)``; ``overrides[(stage, None)]`` holds ``<stage>.<key>=value`` settings and
        ``overrides[(stage, skill)]`` the ``<stage>.<skill>.<key>=value`` ones.
    """
    from pasta.config.overrides import build, split_overrides

    values = split_overrides(items) if not isinstance(items, Mapping) else dict(items)
    own: dict[str, Any] = {}
    overrides: Overrides = {}
    skills_known: list[str] | None = None
    for key, value in values.items():
        if "." not in key:
            if key == "only" and value in ("", None):
                continue
            own[key] = value
            continue
        parts = key.split(".")
        stage = parts[0]
        _check_names([stage], STAGES, "stage")
        if len(parts) == 2 and parts[1]:
            overrides.setdefault((stage, None), {})[parts[1]] = value
        elif len(parts) == 3 and parts[2] and stage in PER_SKILL:
            skills_known = skills_known if skills_known is not None else _known_skills()
            _check_names([parts[1]], skills_known, "skill")
            overrides.setdefault((stage, parts[1]), {})[parts[2]] = value
        else:
            shape = "<stage>.<key>" + (" or <stage>.<skill>.<key>" if stage in PER_SKILL else "")
            raise ConfigError(f"argument '{key}={value}' must look like {shape}=value")
        reserved = RESERVED.get(stage, {}).get(parts[-1])
        if reserved:
            raise ConfigError(f"{key} is set by the pipeline; use {reserved}")
    try:
        cfg = build(PipelineConfig, own, command="pasta pipeline")
    except ConfigError as exc:
        if not str(exc).startswith("unknown key"):
            raise
        raise ConfigError(f"{exc}; a stage's settings take its name as a prefix, e.g. vae.epochs=5 "
                          f"(stages: {', '.join(STAGES)})") from None
    if cfg.num_demos < 1 or cfg.workers < 0:
        raise ConfigError(f"num_demos must be >= 1 and workers >= 0, got {cfg.num_demos} and {cfg.workers}")
    if cfg.variant_demos < -1:
        raise ConfigError(f"variant_demos must be >= 0, or -1 for each variant's own number, got {cfg.variant_demos}")
    return cfg, overrides


# ------------------------------------------------------------------------------------------------- plan


def _unit_values(cfg: PipelineConfig, overrides: Overrides, stage: str, skill: str | None) -> dict[str, Any]:
    """Pipeline defaults < stage defaults < skill defaults < ``<stage>.key`` < ``<stage>.<skill>.key``."""
    values: dict[str, Any] = {}
    if stage == "demos":
        values.update(skill=skill, out=cfg.data, num=cfg.num_demos, workers=cfg.workers)
    else:
        values["progress"] = cfg.progress
    values.update(STAGE_DEFAULTS.get(stage, {}))
    values.update(skill_defaults(stage, skill))
    values.update(overrides.get((stage, None), {}))
    values.update(overrides.get((stage, skill), {}) if skill else {})
    return values


def _build(stage: str, skill: str | None, values: Mapping[str, Any]) -> tuple:
    """The unit's config dataclasses, built by the trainers' own builders (their errors, their hints)."""
    from pasta.config.overrides import build_many

    if stage == "demos":
        from pasta.demos.generate import DemoConfig

        return tuple(build_many(values, [DemoConfig], command="pasta demos"))
    if stage == "reset":
        from pasta.train.reset import reset_configs

        return reset_configs(values, command="pasta train reset")
    if stage == "select":
        from pasta.train.select import SelectConfig

        configs = tuple(build_many(values, [SelectConfig], command="python -m pasta.train.select"))
        configs[0].grid()  # malformed grids fail now
        return configs
    if stage == "policy":
        from pasta.train.policy import LOOP_DEFAULTS, PolicyTrainConfig
        from pasta.train.loop import LoopConfig

        classes = [LoopConfig, PolicyTrainConfig]
        return tuple(build_many({**LOOP_DEFAULTS, **values}, classes, command="pasta train policy"))
    from pasta.train.run import parse_overrides

    return tuple(parse_overrides(stage, {**values, **({"skill": skill} if skill else {})}))


def _directory(cfg: PipelineConfig, stage: str, skill: str | None) -> Path:
    from pasta.nn import COST_DIR, FEASIBILITY_DIR, VAE_DIR
    from pasta.policy import POLICY_DIR

    out = Path(cfg.out)
    return {"demos": lambda: Path(cfg.data) / str(skill), "vae": lambda: out / VAE_DIR,
            "feasibility": lambda: out / FEASIBILITY_DIR / str(skill), "cost": lambda: out / COST_DIR,
            "policy": lambda: out / POLICY_DIR / str(skill), "reset": lambda: out / POLICY_DIR / str(skill),
            "select": lambda: out / POLICY_DIR / str(skill)}[stage]()


def _subset(cfg: PipelineConfig, stage: str, skills: Sequence[str]) -> list[str]:
    """The skills of ``skills`` that a stage of :data:`SKILL_SUBSETS` runs for (its argument, may be empty)."""
    key = SKILL_SUBSETS.get(stage)
    if key is None:
        return list(skills)
    if str(getattr(cfg, key)).strip() == AUTO:
        return [s for s in skills if stage in _skill_class(s).training_defaults]
    names = [n.strip() for n in str(getattr(cfg, key)).split(",") if n.strip()]
    _check_names(names, _known_skills(), "skill")
    return [s for s in skills if s in names]


def _variant_units(cfg: PipelineConfig, skill: str, values: dict[str, Any]) -> list[tuple[str, dict[str, Any]]]:
    """``(unit name, values)`` of the scene-variant demos a skill declares, appended after its default ones."""
    out = []
    for variant, decl in _skill_class(skill).demo_variants.items():
        num = decl.pipeline_demos if cfg.variant_demos < 0 else cfg.variant_demos
        if num > 0:
            out.append((f"demos/{skill}-{variant}", {**values, "num": int(values["num"]) + num, "scene": variant}))
    return out


def plan(cfg: PipelineConfig, overrides: Overrides) -> list[Unit]:
    """Every selected unit, in order, with its configuration built (and so validated)."""
    stages = _names(cfg.stages, "stages")
    _check_names(stages, STAGES, "stage")
    skills = _skills(cfg)
    if "demos" in stages:
        from pasta.demos import check_demo_skill

        for skill in skills:
            check_demo_skill(skill)
    for stage, skill in overrides:
        if stage not in stages:
            print(f"pasta pipeline: warning: {stage}.* settings given but stage {stage} is not in "
                  f"stages={cfg.stages}", file=sys.stderr)
        elif skill is not None and skill not in skills:
            print(f"pasta pipeline: warning: {stage}.{skill}.* settings given but {skill} is not in "
                  f"skills={cfg.skills}", file=sys.stderr)
    units = []
    for stage in (s for s in STAGES if s in stages):
        for skill in (_subset(cfg, stage, skills) if stage in PER_SKILL else [None]):
            values = _unit_values(cfg, overrides, stage, skill)
            name = f"{stage}/{skill}" if skill else stage
            try:
                configs = _build(stage, skill, values)
            except ConfigError as exc:
                raise ConfigError(f"{name}: {exc}") from None
            units.append(Unit(name, stage, skill, values, configs, _directory(cfg, stage, skill)))
            if stage == "demos":
                for vname, vvalues in _variant_units(cfg, str(skill), values):
                    units.append(Unit(vname, stage, skill, vvalues, _build(stage, skill, vvalues),
                                      _directory(cfg, stage, skill)))
    if cfg.only:
        wanted = _names(cfg.only, "only")
        known = [u.name for u in units] + [s for s in stages]
        _check_names(wanted, known, "unit")
        units = [u for u in units if u.name in wanted or u.stage in wanted]
    return units


def _vae_dir(cfg: PipelineConfig, unit: Unit) -> Path:
    from pasta.nn import VAE_DIR

    return Path(unit.configs[1].vae or Path(cfg.out) / VAE_DIR)


def _check_inputs(cfg: PipelineConfig, units: Sequence[Unit]) -> None:
    """Fail now, not after an hour, when a unit's input will not be there."""
    from pasta.io.checkpoint import checkpoint_exists

    stages = {u.stage for u in units}
    if "demos" not in stages and stages - {"demos", "select"}:
        from pasta.demos.data import read_manifest

        try:
            read_manifest(cfg.data)
        except Exception as exc:  # noqa: BLE001 - InputError or OSError, reported as a config problem
            raise ConfigError(f"data={cfg.data}: {exc} (or add demos to stages=)") from None
    if "vae" not in stages:
        for unit in units:
            if unit.stage in USES_VAE and not checkpoint_exists(_vae_dir(cfg, unit)):
                raise ConfigError(f"{unit.name} needs a trained VAE in {_vae_dir(cfg, unit)}; add vae to stages= "
                                  f"(or only=) or set {unit.stage}.vae=DIR")
    trained = {u.skill for u in units if u.stage == "policy"}
    for unit in units:
        if unit.stage == "select" and unit.skill not in trained and not checkpoint_exists(unit.directory):
            raise ConfigError(f"{unit.name} needs a trained policy in {unit.directory}; add policy to stages= "
                              f"(or only=policy/{unit.skill})")
    if "demos" in stages:
        from pasta.demos.generate import validate

        for unit in units:
            if unit.stage == "demos":
                validate(unit.configs[0])


# -------------------------------------------------------------------------------------------- settings


def _demo_counts(data: Path, skill: str | None) -> dict[str, int]:
    skills = [skill] if skill else sorted(p.name for p in data.iterdir() if p.is_dir()) if data.is_dir() else []
    return {s: len(list((data / s).glob("demo_*.npz"))) for s in skills}


def _digest(directory: Path, name: str = "model.safetensors") -> str:
    path = directory / name
    if not path.is_file():
        return "missing"
    h = hashlib.sha256()
    with path.open("rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()[:16]


def settings(cfg: PipelineConfig, unit: Unit) -> dict[str, Any]:
    """What a unit's result depends on, as JSON (compared with the record to decide skip / resume / rerun)."""
    config = {}
    for obj in unit.configs:
        config.update({k: v for k, v in asdict(obj).items() if k not in IGNORED})
    data = Path(cfg.data).resolve()
    if unit.stage == "demos":
        config["out"] = str(data)
        return json.loads(json.dumps({"config": config}))
    if unit.stage == "select":
        # what it scores: the policy's weights and the reset pose beside them (not the demonstrations)
        weights = {name: _digest(unit.directory, name) for name in ("model.safetensors", "reset.safetensors", "reset.json")}
        return json.loads(json.dumps({"config": config, "policy": str(unit.directory.resolve()), "weights": weights}))
    out: dict[str, Any] = {"config": config, "data": str(data), "demos": _demo_counts(data, unit.skill)}
    if unit.stage in USES_VAE:
        out["vae"] = {"path": str(_vae_dir(cfg, unit).resolve()), "weights": _digest(_vae_dir(cfg, unit))}
    return json.loads(json.dumps(out))


# ---------------------------------------------------------------------------------------------- records


def _read_records(out: Path) -> dict[str, Any]:
    path = out / RECORD
    if not path.is_file():
        return {}
    try:
        record = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError):
        print(f"pasta pipeline: warning: {path} is unreadable; every unit reruns", file=sys.stderr)
        return {}
    return record.get("units", {}) if isinstance(record, dict) else {}


def _write_record(out: Path, name: str, entry: dict[str, Any]) -> None:
    out.mkdir(parents=True, exist_ok=True)
    units = _read_records(out)
    units[name] = entry
    path = out / RECORD
    tmp = path.with_name(f".{RECORD}.{os.getpid()}.tmp")
    tmp.write_text(json.dumps({"format": FORMAT, "units": units}, indent=1, sort_keys=True) + "\n")
    os.replace(tmp, path)


def _now() -> str:
    return time.strftime("%Y-%m-%dT%H:%M:%S")


def _figure(stage: str, metrics: Mapping[str, Any]) -> str:
    if stage == "demos":
        return f"{metrics.get('count', 0)} demos" + (f", {metrics['mean_steps']:.1f} steps/demo"
                                                        if metrics.get("mean_steps") else "")
    key = FIGURES[stage]
    value = metrics.get(key)
    if stage == "select" and isinstance(value, (int, float)):
        return (f"rule {metrics.get('done_threshold', 0):g}, {metrics.get('min_steps', 1)}, "
                f"{metrics.get('max_steps') or 'none'}: {key} {value:.4g}")
    return f"{key} {value:.4g}" if isinstance(value, (int, float)) else f"{key} n/a"


def _read_metrics(directory: Path, stage: str = "") -> dict[str, Any] | None:
    """A unit's metrics from its done file (``metrics.json``, or :data:`DONE_FILES`); ``None`` when not done.

    A ``select`` unit's metrics are its selected rule; with ``write`` it is only done while the policy's
    ``model.json`` still holds that rule (a retrained policy's ``model.json`` has none)."""
    try:
        doc = json.loads((directory / DONE_FILES.get(stage, "metrics.json")).read_text())
        if stage != "select":
            return doc
        selected = dict(doc["selected"])
        if doc.get("settings", {}).get("write", True):
            held = json.loads((directory / "model.json").read_text())["config"].get("controller") or {}
            if any(held.get(k) != selected.get(k) for k in ("done_threshold", "min_steps", "max_steps")):
                return None
        return {**selected, "n": doc.get("n"), "seed": doc.get("seed")}
    except (OSError, json.JSONDecodeError, KeyError, TypeError):
        return None


# ---------------------------------------------------------------------------------------------- running


def _demo_status(unit: Unit, record: Mapping[str, Any] | None, current: dict[str, Any]) -> tuple[bool, str]:
    from pasta.demos.generate import pending

    missing = len(pending(unit.configs[0]))
    same = record is not None and record.get("settings") == current
    if record is not None and not same:
        old = {k: v for k, v in record.get("settings", {}).get("config", {}).items() if k != "num"}
        new = {k: v for k, v in current["config"].items() if k != "num"}
        if old != new and missing < unit.configs[0].num:
            changed = sorted(k for k in set(old) | set(new) if old.get(k) != new.get(k))
            print(f"pasta pipeline: warning: {unit.name}: the existing demonstrations were generated with other "
                  f"{', '.join(changed)}; they are kept (delete {unit.directory} to regenerate them)", file=sys.stderr)
    return same and missing == 0, f"{missing} of {unit.configs[0].num} demos to generate"


def _run_demos(cfg: PipelineConfig, unit: Unit, backend: Any = None) -> dict[str, Any]:
    from pasta.demos.generate import generate_demos

    summary = generate_demos(unit.configs[0], progress=cfg.progress, backend=backend)
    return {"count": unit.configs[0].num, "generated": summary["generated"], "mean_steps": summary["mean_steps"]}


def _run_training(cfg: PipelineConfig, unit: Unit) -> dict[str, Any]:
    values = dict(unit.values)
    if unit.stage == "reset":
        from pasta.train.reset import reset_command

        return reset_command(cfg.data, unit.directory, str(unit.skill), values)
    if unit.stage == "select":
        from pasta.train.select import RESULT, select_command

        doc = select_command(cfg.out, str(unit.skill), values, out=unit.directory / RESULT)
        return {**doc["selected"], "n": doc["n"], "seed": doc["seed"]}
    if unit.stage == "policy":
        from pasta.train.policy import train_command

        return train_command(cfg.data, cfg.out, {"skill": unit.skill, **values})
    from pasta.train.run import train

    return train(unit.stage, cfg.data, cfg.out, {**values, **({"skill": unit.skill} if unit.skill else {})})


def _fresh_start(directory: Path, stage: str = "") -> list[str]:
    """Remove what a previous run with other settings left (``last.*``, ``metrics.json``; for the stages
    that share the policy's directory, their own files only, :data:`FRESH_FILES`)."""
    removed = []
    for name in FRESH_FILES.get(stage, ("metrics.json", "last.safetensors", "last.json")):
        path = directory / name
        if path.is_file():
            path.unlink()
            removed.append(name)
    return removed


def _prepare(unit: Unit, record: Mapping[str, Any] | None, current: dict[str, Any], *, resume: bool,
             force: bool) -> str:
    """Get a training unit's directory ready (a fresh start clears the last run's files); say what happens."""
    if resume and unit.stage == "select":
        done = _partial_rows(unit.directory)
        return f"resuming ({done} of {unit.configs[0].n} configs scored)" if done else "restarting (interrupted before its first config)"
    if resume:
        last = "reset_last" if unit.stage == "reset" else "last"
        epoch = _last_epoch(unit.directory, last)
        if epoch is None:
            return "restarting (interrupted before its first epoch ended)"
        return f"resuming from {last}.* ({epoch} of {unit.configs[0].epochs} epochs done)"
    removed = _fresh_start(unit.directory, unit.stage)
    why: list[str] = []
    if force:
        why.append("force=true")
    elif record:
        changed = _changed(record.get("settings"), current)
        why.append(f"changed: {', '.join(changed)}" if changed else "resume=false")
    why += [f"removed the previous {', '.join(removed)}"] if removed else []
    return f"fresh start ({'; '.join(why)})" if why else ""


def _changed(old: Any, new: Any, prefix: str = "") -> list[str]:
    """Dotted names of the settings that differ between two records."""
    if isinstance(old, dict) and isinstance(new, dict):
        return [c for k in sorted(set(old) | set(new)) for c in _changed(old.get(k), new.get(k), f"{prefix}{k}.")]
    return [prefix.rstrip(".") or "settings"] if old != new else []


def _partial_rows(directory: Path) -> int:
    """Configs an interrupted ``select`` unit has scored (rows of its ``select.partial.jsonl``)."""
    from pasta.train.select import PARTIAL

    try:
        return max(0, sum(1 for line in (directory / PARTIAL).read_text().splitlines() if line.strip()) - 1)
    except OSError:
        return 0


def _last_epoch(directory: Path, last: str = "last") -> int | None:
    try:
        return int(json.loads((directory / f"{last}.json").read_text())["state"]["epoch"]) + 1
    except (OSError, KeyError, TypeError, ValueError):
        return None


def run_pipeline(items: Sequence[str] | Mapping[str, Any], *,
                 echo: Callable[[str], None] | None = None) -> list[UnitResult]:
    """Run ``pasta pipeline`` with ``items`` (``key=value`` strings or a mapping); return one result per unit.

    Raises:
        ConfigError: bad arguments (before any work starts), or a unit's own configuration error.
    """
    from pasta.distributed import split_backend_args

    say = echo or (lambda line: print(line, flush=True))
    backend, items = split_backend_args(items)  # backend= and ray.* go to the demos units, not to a stage
    backend.check()
    cfg, overrides = parse_arguments(items)
    units = plan(cfg, overrides)
    _check_inputs(cfg, units)
    out = Path(cfg.out)
    results: list[UnitResult] = []
    n = len(units)
    say(f"pasta pipeline: {n} unit(s): {', '.join(u.name for u in units)}; data={cfg.data} out={cfg.out}"
        + (" force=true" if cfg.force else "") + (f" backend={backend.describe()}" if backend.name != "local" else ""))
    try:
        for i, unit in enumerate(units, 1):
            tag = f"[{i}/{n}] {unit.name}"
            current = settings(cfg, unit)
            record = _read_records(out).get(unit.name)
            same = record is not None and record.get("settings") == current
            if unit.stage == "demos":
                done, todo = _demo_status(unit, record, current)
                metrics = record.get("metrics", {}) if done and record else None
            else:
                metrics = _read_metrics(unit.directory, unit.stage) if same else None
                done, todo = metrics is not None, ""
            if done and not cfg.force:
                figure = _figure(unit.stage, metrics or {})
                say(f"{tag} skipped: done with the same settings ({figure})")
                results.append(UnitResult(unit.name, "skipped", 0.0, figure, dict(metrics or {})))
                continue
            note = todo if unit.stage == "demos" else _prepare(unit, record, current, force=cfg.force,
                                                               resume=same and not cfg.force and getattr(unit.configs[0], "resume", True))
            say(f"{tag} ... {note}".rstrip())
            started = _now()
            _write_record(out, unit.name, {"settings": current, "status": "running", "started": started})
            t0 = time.perf_counter()
            try:
                metrics = _run_demos(cfg, unit, backend) if unit.stage == "demos" else _run_training(cfg, unit)
            except BaseException as exc:
                wall = time.perf_counter() - t0
                status = "interrupted" if isinstance(exc, KeyboardInterrupt) else "failed"
                hint = "; run the same command again to resume" if status == "interrupted" else ""
                say(f"{tag} {status} after {wall:.1f} s{hint}")
                results.append(UnitResult(unit.name, status, wall))
                raise
            wall = time.perf_counter() - t0
            figure = _figure(unit.stage, metrics)
            entry = {"settings": current, "status": "done", "started": started, "finished": _now(),
                     "wall_s": round(wall, 2), "figure": figure}
            _write_record(out, unit.name, {**entry, **({"metrics": metrics} if unit.stage == "demos" else {})})
            say(f"{tag} done in {wall:.1f} s: {figure}")
            results.append(UnitResult(unit.name, "ran", wall, figure, dict(metrics)))
    finally:
        if results:
            say(summary_table(results))
    return results


def summary_table(results: Sequence[UnitResult]) -> str:
    """A plain-text table: unit, status, wall seconds, figure."""
    rows = [("unit", "status", "wall s", "figure")]
    rows += [(r.name, r.status, f"{r.wall_s:.1f}" if r.status != "skipped" else "-", r.figure or "-") for r in results]
    widths = [max(len(row[c]) for row in rows) for c in range(3)]
    lines = [f"{a:<{widths[0]}}  {b:<{widths[1]}}  {c:>{widths[2]}}  {d}" for a, b, c, d in rows]
    total = sum(r.wall_s for r in results)
    ran = sum(r.status == "ran" for r in results)
    lines.insert(1, "-" * max(len(line) for line in lines))
    lines.append(f"{ran} ran, {sum(r.status == 'skipped' for r in results)} skipped, {total:.1f} s in all")
    return "\n".join(lines)
