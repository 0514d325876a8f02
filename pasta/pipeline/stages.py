"""The stages of ``pasta pipeline``, one :class:`Stage` record each, in the order their units run.

A record says everything the generic runner (:mod:`pasta.pipeline.run`) needs of a stage: its name, whether
it has one unit per skill, its pipeline defaults, the trainer's config builder and runner, where a unit
writes, which file marks a unit done and what a fresh start removes, the keys the pipeline sets itself,
the held-out figure it reports and what its result depends on. Two stages differ in more than data:
``demos`` (it fills in missing files instead of training, and adds the scene-variant units) and ``select``
(it scores the trained policy, resumes per config, and is done only while ``model.json`` holds its rule);
they are :class:`Stage` subclasses that override those methods.

The stage records name no skill: a skill plugin's :attr:`pasta.core.Skill.training_defaults` go over a
stage's :attr:`Stage.defaults`, and listing an optional stage there (``reset``, ``select``) opts it in.
"""

from __future__ import annotations

import hashlib
import json
import sys
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pasta.core.errors import ConfigError
from pasta.nn import COST_DIR, FEASIBILITY_DIR, VAE_DIR
from pasta.policy import POLICY_DIR

if TYPE_CHECKING:
    from pasta.core import Skill
    from pasta.pipeline.run import PipelineConfig, Unit

__all__ = ["STAGES", "Stage", "stage"]

#: keys set on every unit of a stage: sized for a 2-core CPU (each trainer's own defaults otherwise)
ONE_THREAD = {"threads": 1}
_FLAT = "`pasta train <module> flat=true` for the Flat 3D baseline (the pipeline trains the entity models)"


@dataclass(frozen=True)
class Stage:
    """One stage of the pipeline: a trainer of the shared loop, unless a subclass says otherwise.

    Attributes:
        name: the stage's name: ``<name>.<key>=value`` sets its units, ``<name>/<skill>`` names a unit.
        per_skill: one unit per skill (else a single unit over every skill's data).
        command: the command whose keys the stage takes (in error messages and the help).
        build: ``(values, skill) -> configs``: the trainer's own config builder (so a typo gets its "did
            you mean" before any work starts).
        run: ``(pipeline config, unit, backend) -> metrics``: produce the unit (the backend makes the
            demonstrations; the training units run in this process).
        directory: ``(pipeline config, skill) -> Path``: where a unit writes.
        figure: the held-out figure reported for a unit (a key of its metrics).
        defaults: the pipeline's settings of every unit (a skill plugin's ``training_defaults`` for this
            stage go over them); with each trainer's defaults, the settings of the shipped models.
        done_file: the file in the unit's directory whose presence (with a matching record) marks it done.
        last: the shared loop's resume checkpoint in that directory (``None``: the stage keeps none).
        extra_fresh: other files a fresh start removes, besides the done file and ``last.*``.
        reserved: keys the pipeline sets itself, and the argument to use instead.
        skills_arg: the pipeline argument naming the skills of an optional stage (``auto``: the skills
            whose ``training_defaults`` list the stage); ``None``: every skill of ``skills=``.
        reads_data: the stage reads the dataset (its manifest must exist when the demos stage does not run).
        uses_vae: the stage encodes with the trained VAE (its weights are part of a unit's settings).
    """

    name: str
    per_skill: bool
    command: str
    build: Callable[[Mapping[str, Any], str | None], tuple]
    run: Callable[[PipelineConfig, Unit, Any], dict[str, Any]]
    directory: Callable[[PipelineConfig, str | None], Path]
    figure: str
    defaults: Mapping[str, Any] = field(default_factory=dict)
    done_file: str = "metrics.json"
    last: str | None = "last"
    extra_fresh: tuple[str, ...] = ()
    reserved: Mapping[str, str] = field(default_factory=dict)
    skills_arg: str | None = None
    reads_data: bool = True
    uses_vae: bool = False

    @property
    def fresh_files(self) -> tuple[str, ...]:
        """What a fresh start removes from a unit's directory (never another stage's files there)."""
        last = (f"{self.last}.safetensors", f"{self.last}.json") if self.last else ()
        return (self.done_file, *last, *self.extra_fresh)

    # -- planning -------------------------------------------------------------------------------------

    def base_values(self, cfg: PipelineConfig, skill: str | None) -> dict[str, Any]:
        """The settings the pipeline hands every unit before the stage's defaults."""
        return {"progress": cfg.progress}

    def variant_units(self, cfg: PipelineConfig, skill: str, values: dict[str, Any]) -> list[tuple[str, dict[str, Any]]]:
        """Further ``(unit name, values)`` after a skill's unit (none)."""
        return []

    def check_inputs(self, cfg: PipelineConfig, unit: Unit, units: Sequence[Unit]) -> None:
        """Fail now, not after an hour, when the unit's input will not be there (the VAE it encodes with)."""
        from pasta.io.checkpoint import checkpoint_exists

        if self.uses_vae and "vae" not in {u.stage for u in units} and not checkpoint_exists(vae_dir(cfg, unit)):
            raise ConfigError(f"{unit.name} needs a trained VAE in {vae_dir(cfg, unit)}; add vae to stages= "
                              f"(or only=) or set {self.name}.vae=DIR")

    # -- what a unit depends on, and whether it is done ------------------------------------------------

    def settings(self, cfg: PipelineConfig, unit: Unit, config: dict[str, Any]) -> dict[str, Any]:
        """What the unit's result depends on besides ``config``: the dataset (absolute path and
        demonstrations per skill) and, for a stage that encodes, the VAE weights."""
        data = Path(cfg.data).resolve()
        out: dict[str, Any] = {"config": config, "data": str(data), "demos": _demo_counts(data, unit.skill)}
        if self.uses_vae:
            out["vae"] = {"path": str(vae_dir(cfg, unit).resolve()), "weights": digest(vae_dir(cfg, unit))}
        return out

    def done(self, unit: Unit, record: Mapping[str, Any] | None, current: dict[str, Any]) -> dict[str, Any] | None:
        """The unit's metrics when it is done (its record holds ``current`` and its done file exists), else ``None``."""
        if record is None or record.get("settings") != current:
            return None
        try:
            return json.loads((unit.directory / self.done_file).read_text())
        except (OSError, json.JSONDecodeError):
            return None

    def prepare(self, unit: Unit, record: Mapping[str, Any] | None, current: dict[str, Any], *, resume: bool,
                force: bool) -> str:
        """Get the unit's directory ready (a fresh start removes the last run's files); say what happens."""
        if resume:
            epoch = _last_epoch(unit.directory, self.last) if self.last else None
            if epoch is None:
                return "restarting (interrupted before its first epoch ended)"
            return f"resuming from {self.last}.* ({epoch} of {unit.configs[0].epochs} epochs done)"
        removed = [name for name in self.fresh_files if _remove(unit.directory / name)]
        why: list[str] = []
        if force:
            why.append("force=true")
        elif record:
            changed = _changed(record.get("settings"), current)
            why.append(f"changed: {', '.join(changed)}" if changed else "resume=false")
        why += [f"removed the previous {', '.join(removed)}"] if removed else []
        return f"fresh start ({'; '.join(why)})" if why else ""

    def describe(self, metrics: Mapping[str, Any]) -> str:
        """The unit's held-out figure, for its line and the summary table."""
        value = metrics.get(self.figure)
        return f"{self.figure} {value:.4g}" if isinstance(value, (int, float)) else f"{self.figure} n/a"

    #: whether the unit's metrics go into its ``pipeline.json`` entry (when it has no done file of its own)
    keep_metrics = False


class DemosStage(Stage):
    """``demos/<skill>``: ``pasta demos`` fills in the missing demonstrations (it never rewrites a file), and a
    skill's scene variants add units ``demos/<skill>-<variant>`` after its default ones."""

    keep_metrics = True

    def base_values(self, cfg: PipelineConfig, skill: str | None) -> dict[str, Any]:
        return {"skill": skill, "out": cfg.data, "num": cfg.num_demos, "workers": cfg.workers}

    def variant_units(self, cfg: PipelineConfig, skill: str, values: dict[str, Any]) -> list[tuple[str, dict[str, Any]]]:
        # each variant takes the indices after the previous one's (``num`` is the dataset's size after the unit)
        out, total = [], int(values["num"])
        for variant, decl in skill_class(skill).demo_variants.items():
            num = decl.pipeline_demos if cfg.variant_demos < 0 else cfg.variant_demos
            if num > 0:
                total += num
                out.append((f"demos/{skill}-{variant}", {**values, "num": total, "scene": variant}))
        return out

    def check_inputs(self, cfg: PipelineConfig, unit: Unit, units: Sequence[Unit]) -> None:
        from pasta.demos.generate import validate

        validate(unit.configs[0])

    def settings(self, cfg: PipelineConfig, unit: Unit, config: dict[str, Any]) -> dict[str, Any]:
        return {"config": {**config, "out": str(Path(cfg.data).resolve())}}

    def done(self, unit: Unit, record: Mapping[str, Any] | None, current: dict[str, Any]) -> dict[str, Any] | None:
        """Done when the record matches and every file exists; warns when existing files were made otherwise."""
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
        return dict(record.get("metrics", {})) if record is not None and same and missing == 0 else None

    def prepare(self, unit: Unit, record: Mapping[str, Any] | None, current: dict[str, Any], *, resume: bool,
                force: bool) -> str:
        from pasta.demos.generate import pending

        return f"{len(pending(unit.configs[0]))} of {unit.configs[0].num} demos to generate"

    def describe(self, metrics: Mapping[str, Any]) -> str:
        return f"{metrics.get('count', 0)} demos" + (f", {metrics['mean_steps']:.1f} steps/demo"
                                                        if metrics.get("mean_steps") else "")


class SelectStage(Stage):
    """``select/<skill>``: scores the trained policy (and the reset pose beside it) on validation configs, so
    its settings are their weights, not the demonstrations; an interrupted unit resumes at the next config;
    with ``write`` it is done only while the policy's ``model.json`` still holds the rule it chose."""

    def check_inputs(self, cfg: PipelineConfig, unit: Unit, units: Sequence[Unit]) -> None:
        from pasta.io.checkpoint import checkpoint_exists

        trained = {u.skill for u in units if u.stage == "policy"}
        if unit.skill not in trained and not checkpoint_exists(unit.directory):
            raise ConfigError(f"{unit.name} needs a trained policy in {unit.directory}; add policy to stages= "
                              f"(or only=policy/{unit.skill})")

    def settings(self, cfg: PipelineConfig, unit: Unit, config: dict[str, Any]) -> dict[str, Any]:
        weights = {name: digest(unit.directory, name) for name in ("model.safetensors", "reset.safetensors", "reset.json")}
        return {"config": config, "policy": str(unit.directory.resolve()), "weights": weights}

    def done(self, unit: Unit, record: Mapping[str, Any] | None, current: dict[str, Any]) -> dict[str, Any] | None:
        if record is None or record.get("settings") != current:
            return None
        try:
            doc = json.loads((unit.directory / self.done_file).read_text())
            selected = dict(doc["selected"])
            if doc.get("settings", {}).get("write", True):
                held = json.loads((unit.directory / "model.json").read_text())["config"].get("controller") or {}
                if any(held.get(k) != selected.get(k) for k in ("done_threshold", "min_steps", "max_steps")):
                    return None
            return {**selected, "n": doc.get("n"), "seed": doc.get("seed")}
        except (OSError, json.JSONDecodeError, KeyError, TypeError):
            return None

    def prepare(self, unit: Unit, record: Mapping[str, Any] | None, current: dict[str, Any], *, resume: bool,
                force: bool) -> str:
        if resume:
            done = _partial_rows(unit.directory)
            return (f"resuming ({done} of {unit.configs[0].n} configs scored)" if done
                    else "restarting (interrupted before its first config)")
        return super().prepare(unit, record, current, resume=resume, force=force)

    def describe(self, metrics: Mapping[str, Any]) -> str:
        value = metrics.get(self.figure)
        if isinstance(value, (int, float)):
            return (f"rule {metrics.get('done_threshold', 0):g}, {metrics.get('min_steps', 1)}, "
                    f"{metrics.get('max_steps') or 'none'}: {self.figure} {value:.4g}")
        return super().describe(metrics)


# ------------------------------------------------------------------------------------- builders, runners


def _build_demos(values: Mapping[str, Any], skill: str | None) -> tuple:
    from pasta.config.overrides import build_many
    from pasta.demos.generate import DemoConfig

    return tuple(build_many(values, [DemoConfig], command="pasta demos"))


def _build_module(name: str) -> Callable[[Mapping[str, Any], str | None], tuple]:
    def build(values: Mapping[str, Any], skill: str | None) -> tuple:
        from pasta.train.run import parse_overrides

        return tuple(parse_overrides(name, {**values, **({"skill": skill} if skill else {})}))

    return build


def _build_policy(values: Mapping[str, Any], skill: str | None) -> tuple:
    from pasta.train.policy import policy_configs

    return policy_configs(values)


def _build_reset(values: Mapping[str, Any], skill: str | None) -> tuple:
    from pasta.train.reset import reset_configs

    return reset_configs(values)


def _build_select(values: Mapping[str, Any], skill: str | None) -> tuple:
    from pasta.train.select import select_config

    return (select_config(values),)


def _run_demos(cfg: PipelineConfig, unit: Unit, backend: Any) -> dict[str, Any]:
    from pasta.demos.generate import generate_demos

    summary = generate_demos(unit.configs[0], progress=cfg.progress, backend=backend)
    return {"count": unit.configs[0].num, "generated": summary["generated"], "mean_steps": summary["mean_steps"]}


def _run_module(name: str) -> Callable[[PipelineConfig, Unit, Any], dict[str, Any]]:
    def run(cfg: PipelineConfig, unit: Unit, backend: Any = None) -> dict[str, Any]:
        from pasta.train.run import train

        return train(name, cfg.data, cfg.out, {**unit.values, **({"skill": unit.skill} if unit.skill else {})})

    return run


def _run_policy(cfg: PipelineConfig, unit: Unit, backend: Any = None) -> dict[str, Any]:
    from pasta.train.policy import train_command

    return train_command(cfg.data, cfg.out, {"skill": unit.skill, **unit.values})


def _run_reset(cfg: PipelineConfig, unit: Unit, backend: Any = None) -> dict[str, Any]:
    from pasta.train.reset import reset_command

    return reset_command(cfg.data, unit.directory, str(unit.skill), dict(unit.values))


def _run_select(cfg: PipelineConfig, unit: Unit, backend: Any = None) -> dict[str, Any]:
    from pasta.train.select import RESULT, select_command

    doc = select_command(cfg.out, str(unit.skill), dict(unit.values), out=unit.directory / RESULT)
    return {**doc["selected"], "n": doc["n"], "seed": doc["seed"]}


def _in_data(cfg: PipelineConfig, skill: str | None) -> Path:
    return Path(cfg.data) / str(skill)


def _under_out(sub: str, per_skill: bool) -> Callable[[PipelineConfig, str | None], Path]:
    return lambda cfg, skill: Path(cfg.out) / sub / str(skill) if per_skill else Path(cfg.out) / sub


#: the stages in the order their units run
STAGES: tuple[Stage, ...] = (
    DemosStage("demos", per_skill=True, command="pasta demos", build=_build_demos, run=_run_demos,
               directory=_in_data, figure="count", last=None, reads_data=False,
               reserved={"skill": "skills=", "out": "data="}),
    Stage("vae", per_skill=False, command="pasta train vae", build=_build_module("vae"), run=_run_module("vae"),
          directory=_under_out(VAE_DIR, False), figure="heldout_chamfer_mean",
          defaults={"epochs": 11, "stride": 5, **ONE_THREAD}, reserved={"flat": _FLAT}),
    Stage("feasibility", per_skill=True, command="pasta train feasibility", build=_build_module("feasibility"),
          run=_run_module("feasibility"), directory=_under_out(FEASIBILITY_DIR, True), figure="heldout_auc_hard",
          defaults=ONE_THREAD, reserved={"skill": "skills=", "flat": _FLAT}, uses_vae=True),
    Stage("cost", per_skill=False, command="pasta train cost", build=_build_module("cost"), run=_run_module("cost"),
          directory=_under_out(COST_DIR, False), figure="heldout_spearman", defaults={"stride": 5, **ONE_THREAD},
          reserved={"flat": _FLAT}, uses_vae=True),
    Stage("policy", per_skill=True, command="pasta train policy", build=_build_policy, run=_run_policy,
          directory=_under_out(POLICY_DIR, True), figure="heldout_action",
          defaults={"epochs": 40, "steps_per_epoch": 50, **ONE_THREAD}, reserved={"skill": "skills="}),
    # reset and select write into the policy's directory, with their own done and resume files
    Stage("reset", per_skill=True, command="pasta train reset", build=_build_reset, run=_run_reset,
          directory=_under_out(POLICY_DIR, True), figure="heldout_mae_m", defaults=ONE_THREAD,
          done_file="reset_metrics.json", last="reset_last", skills_arg="reset_skills",
          reserved={"skill": "skills= and reset_skills=", "data": "data=", "out": "out="}),
    SelectStage("select", per_skill=True, command="pasta train select", build=_build_select, run=_run_select,
                directory=_under_out(POLICY_DIR, True), figure="mean_ni", defaults={"n": 20, "seed": 2000, "write": True,
                                                                                  **ONE_THREAD},
                done_file="select.json", last=None, extra_fresh=("select.partial.jsonl",), skills_arg="select_skills",
                reads_data=False, reserved={"skill": "skills= and select_skills=", "models": "out=", "out": "out="}),
)
_BY_NAME = {s.name: s for s in STAGES}


def stage(name: str) -> Stage:
    """The stage record called ``name``."""
    return _BY_NAME[name]


# ---------------------------------------------------------------------------------------------- helpers


def skill_class(name: str) -> type[Skill]:
    from pasta.plugins import get_plugins

    return get_plugins().skills.load(name)


def vae_dir(cfg: PipelineConfig, unit: Unit) -> Path:
    """The VAE a feasibility or cost unit encodes with: its ``vae=`` setting, else ``OUT/vae`` once trained, else the
    shipped one (as the trainers choose: a root that trains only a new skill encodes with the shipped latents)."""
    from pasta.weights import module_dir

    return Path(unit.configs[1].vae or module_dir(cfg.out, VAE_DIR))


def digest(directory: Path, name: str = "model.safetensors") -> str:
    """The first 16 hex digits of the file's SHA-256 (``"missing"`` when there is none)."""
    path = directory / name
    if not path.is_file():
        return "missing"
    h = hashlib.sha256()
    with path.open("rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()[:16]


def _demo_counts(data: Path, skill: str | None) -> dict[str, int]:
    skills = [skill] if skill else sorted(p.name for p in data.iterdir() if p.is_dir()) if data.is_dir() else []
    return {s: len(list((data / s).glob("demo_*.npz"))) for s in skills}


def _remove(path: Path) -> bool:
    if path.is_file():
        path.unlink()
        return True
    return False


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


def _last_epoch(directory: Path, last: str) -> int | None:
    try:
        return int(json.loads((directory / f"{last}.json").read_text())["state"]["epoch"]) + 1
    except (OSError, KeyError, TypeError, ValueError):
        return None
