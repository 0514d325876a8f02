"""``pasta pipeline``: demonstrations and every learned module in one resumable run.

Units run in this order, each one a ``pasta demos`` or ``pasta train <stage>`` call (the stages are the
records of :mod:`pasta.pipeline.stages`; this module is the generic runner)::

    demos/<skill> (+ demos/<skill>-<variant>) -> vae -> feasibility/<skill> -> cost -> policy/<skill>
        -> reset/<skill> -> select/<skill>

The skills are every registered skill that can make demonstrations (:func:`pasta.demos.demo_skills`)
unless ``skills=`` names some. Each skill's plugin brings its own settings
(:attr:`pasta.core.Skill.training_defaults`, applied over the stage's :attr:`~pasta.pipeline.stages.Stage.defaults`)
and the scene variants
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
this process, one after the other (each depends on the last, or trains on every skill's data).
``deadline_s=`` goes to the demos units too (a worker still on one demo after it is given up; 0: each
unit's :func:`pasta.demos.generate.demo_deadline`). Neither is part of a unit's settings: changing them
never reruns a unit. See docs/scaling.md.

Every unit's configuration is built up front with the trainers' own config builders, so a typo in
``<stage>.<key>=value`` fails with their "did you mean" message before any work starts.
"""

from __future__ import annotations

import json
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from pasta.core.errors import ConfigError, did_you_mean
from pasta.core.files import OutputLock, write_json
from pasta.pipeline.stages import STAGES, Stage, skill_class, stage

__all__ = ["PipelineConfig", "Unit", "UnitResult", "parse_arguments", "plan", "run_pipeline", "run_units", "settings",
           "skill_defaults", "summary_table"]

FORMAT = "pasta-pipeline/1"
RECORD = "pipeline.json"
#: the stage names, in the order their units run
NAMES = tuple(s.name for s in STAGES)
#: value of ``skills``, ``reset_skills`` and ``select_skills`` that means "what the skill plugins ask for"
AUTO = "auto"
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
        threads: CPU threads of every unit (torch's in the training units, the simulator's in the demos
            units), over the stages' own (1 for training, the simulator's default for demos); 0: those;
            ``<stage>.threads=`` still wins. Never causes a rerun.
    """

    data: str = "data/demos"
    out: str = "models"
    num_demos: int = 200
    variant_demos: int = -1
    workers: int = 2
    stages: str = ",".join(s.name for s in STAGES)
    skills: str = AUTO
    reset_skills: str = AUTO
    select_skills: str = AUTO
    force: bool = False
    only: str = ""
    progress: bool = True
    threads: int = 0

    def __post_init__(self) -> None:
        from pasta.config.validate import check_int, check_threads
        from pasta.demos.generate import MAX_DEMOS
        from pasta.distributed import MAX_WORKERS

        check_int(self.num_demos, "num_demos", low=1, high=MAX_DEMOS)
        try:
            check_int(self.variant_demos, "variant_demos", low=-1, high=MAX_DEMOS)
        except ConfigError as exc:
            raise ConfigError(f"{exc} (-1: each variant's own number, 0: none)") from None
        check_int(self.workers, "workers", low=0, high=MAX_WORKERS)
        check_threads(self.threads, "threads")


@dataclass
class Unit:
    """One step of the pipeline: a demos run of one skill, or one trained module.

    Attributes:
        name: ``stage`` or ``stage/skill``.
        stage: the name of its :class:`~pasta.pipeline.stages.Stage`.
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


def skill_defaults(stage_name: str, skill: str | None) -> dict[str, Any]:
    """The pipeline settings the plugin of ``skill`` asks for in a stage (its ``training_defaults``)."""
    if not skill:
        return {}
    return dict(skill_class(skill).training_defaults.get(stage_name) or {})


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
        name = parts[0]
        _check_names([name], NAMES, "stage")
        per_skill = stage(name).per_skill
        if len(parts) == 2 and parts[1]:
            overrides.setdefault((name, None), {})[parts[1]] = value
        elif len(parts) == 3 and parts[2] and per_skill:
            skills_known = skills_known if skills_known is not None else _known_skills()
            _check_names([parts[1]], skills_known, "skill")
            overrides.setdefault((name, parts[1]), {})[parts[2]] = value
        else:
            shape = "<stage>.<key>" + (" or <stage>.<skill>.<key>" if per_skill else "")
            raise ConfigError(f"argument '{key}={value}' must look like {shape}=value")
        reserved = stage(name).reserved.get(parts[-1])
        if reserved:
            raise ConfigError(f"{key} is set by the pipeline; use {reserved}")
    try:
        cfg = build(PipelineConfig, own, command="pasta pipeline")
    except ConfigError as exc:
        if not str(exc).startswith("unknown key"):
            raise
        raise ConfigError(f"{exc}; a stage's settings take its name as a prefix, e.g. vae.epochs=5 "
                          f"(stages: {', '.join(NAMES)})") from None
    return cfg, overrides


# ------------------------------------------------------------------------------------------------- plan


def _unit_values(cfg: PipelineConfig, overrides: Overrides, st: Stage, skill: str | None) -> dict[str, Any]:
    """Pipeline values < stage defaults < skill defaults < ``threads=N`` < ``<stage>.key`` < ``<stage>.<skill>.key``."""
    values = st.base_values(cfg, skill)
    values.update(st.defaults)
    values.update(skill_defaults(st.name, skill))
    if cfg.threads:  # the pipeline's threads=N over the stages' threads=1, which are sized for a 2-core CPU
        values["threads"] = cfg.threads
    values.update(overrides.get((st.name, None), {}))
    values.update(overrides.get((st.name, skill), {}) if skill else {})
    return values


def _stage_skills(cfg: PipelineConfig, st: Stage, skills: Sequence[str]) -> list[str | None]:
    """The skills a stage has units for: none for a single-unit stage, else ``skills`` (for an optional
    stage, those its argument names; ``auto``: those whose plugin lists the stage)."""
    if not st.per_skill:
        return [None]
    if st.skills_arg is None:
        return list(skills)
    given = str(getattr(cfg, st.skills_arg)).strip()
    if given == AUTO:
        return [s for s in skills if st.name in skill_class(s).training_defaults]
    names = [n.strip() for n in given.split(",") if n.strip()]
    _check_names(names, _known_skills(), "skill")
    return [s for s in skills if s in names]


def _unit(cfg: PipelineConfig, st: Stage, name: str, skill: str | None, values: dict[str, Any]) -> Unit:
    try:
        configs = tuple(st.build(values, skill))
    except ConfigError as exc:
        raise ConfigError(f"{name}: {exc}") from None
    return Unit(name, st.name, skill, values, configs, st.directory(cfg, skill))


def plan(cfg: PipelineConfig, overrides: Overrides) -> list[Unit]:
    """Every selected unit, in order, with its configuration built (and so validated)."""
    stages = _names(cfg.stages, "stages")
    _check_names(stages, NAMES, "stage")
    skills = _skills(cfg)
    if "demos" in stages:
        from pasta.demos import check_demo_skill

        for s in skills:
            check_demo_skill(s)
    for name, skill in overrides:
        if name not in stages:
            print(f"pasta pipeline: warning: {name}.* settings given but stage {name} is not in "
                  f"stages={cfg.stages}", file=sys.stderr)
        elif skill is not None and skill not in skills:
            print(f"pasta pipeline: warning: {name}.{skill}.* settings given but {skill} is not in "
                  f"skills={cfg.skills}", file=sys.stderr)
    units = []
    for st in (s for s in STAGES if s.name in stages):
        for skill in _stage_skills(cfg, st, skills):
            values = _unit_values(cfg, overrides, st, skill)
            units.append(_unit(cfg, st, f"{st.name}/{skill}" if skill else st.name, skill, values))
            for vname, vvalues in st.variant_units(cfg, skill, values) if skill else ():
                units.append(_unit(cfg, st, vname, skill, vvalues))
    if cfg.only:
        wanted = _names(cfg.only, "only")
        known = [u.name for u in units] + list(stages)
        _check_names(wanted, known, "unit")
        units = [u for u in units if u.name in wanted or u.stage in wanted]
    return units


def _check_inputs(cfg: PipelineConfig, units: Sequence[Unit]) -> None:
    """Fail now, not after an hour, when a unit's input will not be there."""
    stages = {u.stage for u in units}
    if "demos" not in stages and any(stage(s).reads_data for s in stages):
        from pasta.demos.data import read_manifest

        try:
            read_manifest(cfg.data)
        except Exception as exc:  # noqa: BLE001 - InputError or OSError, reported as a config problem
            raise ConfigError(f"data={cfg.data}: {exc} (or add demos to stages=)") from None
    for unit in units:
        stage(unit.stage).check_inputs(cfg, unit, units)


# -------------------------------------------------------------------------------------------- settings


def settings(cfg: PipelineConfig, unit: Unit) -> dict[str, Any]:
    """What a unit's result depends on, as JSON (compared with the record to decide skip / resume / rerun):
    its resolved configuration (less :data:`IGNORED`) and what its stage adds (:meth:`Stage.settings`)."""
    config = {}
    for obj in unit.configs:
        config.update({k: v for k, v in asdict(obj).items() if k not in IGNORED})
    return json.loads(json.dumps(stage(unit.stage).settings(cfg, unit, config)))


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
    write_json(out / RECORD, {"format": FORMAT, "units": units}, indent=1, sort_keys=True)


def _now() -> str:
    return time.strftime("%Y-%m-%dT%H:%M:%S")


# ---------------------------------------------------------------------------------------------- running


def run_pipeline(items: Sequence[str] | Mapping[str, Any], *,
                 echo: Callable[[str], None] | None = None) -> list[UnitResult]:
    """Run ``pasta pipeline`` with ``items`` (``key=value`` strings or a mapping); return one result per unit.

    Raises:
        ConfigError: bad arguments (before any work starts), or a unit's own configuration error.
    """
    from pasta.distributed import split_backend_args

    say = echo or (lambda line: print(line, flush=True))
    backend, items = split_backend_args(items)  # backend=, deadline_s= and ray.* go to the demos units, not to a stage
    backend.check()
    cfg, overrides = parse_arguments(items)
    units = plan(cfg, overrides)
    _check_inputs(cfg, units)  # every argument is checked before the first unit runs
    return run_units(cfg, units, backend, say)


def run_units(cfg: PipelineConfig, units: Sequence[Unit], backend: Any, say: Callable[[str], None]) -> list[UnitResult]:
    """Run the checked, planned ``units`` in order (done ones are skipped); return one result per unit."""
    out = Path(cfg.out)
    lock = OutputLock(out, "out").acquire()  # one pipeline per models root
    results: list[UnitResult] = []
    n = len(units)
    say(f"pasta pipeline: {n} unit(s): {', '.join(u.name for u in units)}; data={cfg.data} out={cfg.out}"
        + (" force=true" if cfg.force else "") + (f" backend={backend.describe()}" if backend.name != "local" else ""))
    try:
        for i, unit in enumerate(units, 1):
            st = stage(unit.stage)
            tag = f"[{i}/{n}] {unit.name}"
            current = settings(cfg, unit)
            record = _read_records(out).get(unit.name)
            metrics = st.done(unit, record, current)
            if metrics is not None and not cfg.force:
                figure = st.describe(metrics)
                say(f"{tag} skipped: done with the same settings ({figure})")
                results.append(UnitResult(unit.name, "skipped", 0.0, figure, dict(metrics)))
                continue
            same = record is not None and record.get("settings") == current
            resume = same and not cfg.force and getattr(unit.configs[0], "resume", True)
            note = st.prepare(unit, record, current, resume=resume, force=cfg.force)
            say(f"{tag} ... {note}".rstrip())
            started = _now()
            _write_record(out, unit.name, {"settings": current, "status": "running", "started": started})
            t0 = time.perf_counter()
            try:
                metrics = st.run(cfg, unit, backend)
            except BaseException as exc:
                wall = time.perf_counter() - t0
                status = "interrupted" if isinstance(exc, KeyboardInterrupt) else "failed"
                hint = "; run the same command again to resume" if status == "interrupted" else ""
                say(f"{tag} {status} after {wall:.1f} s{hint}")
                results.append(UnitResult(unit.name, status, wall))
                raise
            wall = time.perf_counter() - t0
            figure = st.describe(metrics)
            entry = {"settings": current, "status": "done", "started": started, "finished": _now(),
                     "wall_s": round(wall, 2), "figure": figure}
            _write_record(out, unit.name, {**entry, **({"metrics": metrics} if st.keep_metrics else {})})
            say(f"{tag} done in {wall:.1f} s: {figure}")
            results.append(UnitResult(unit.name, "ran", wall, figure, dict(metrics)))
    finally:
        lock.release()
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
