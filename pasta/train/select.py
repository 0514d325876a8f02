"""Choose the learned controller's stopping rule (done threshold, ``min_steps``, ``max_steps``) on validation configs.

The learned controller stops at its first step ``i`` (``i + 1 >= min_steps`` actions) whose done
probability exceeds ``done_threshold``, or after ``max_steps`` actions
(:class:`pasta.policy.learned.PolicyController`). Up to that step
the rollout does not depend on the rule (the controller's point subsampling is seeded, the simulator is
deterministic), so one rollout that never stops, with the simulator state and the done probability
recorded at every step, scores every rule: restore the state where the rule stops, let the dough settle
(the idle steps of :func:`pasta.tasks.step.run_skill`) and measure the normalised improvement.

Use validation configs (a config stream the test table does not use, e.g. ``seed=2000``), then report
the chosen rule on the test configs (``seed=1000``) with ``pasta train evaluate`` (:mod:`pasta.train.evaluate`)::

    pasta train select out=MODELS skill=roll [n=20] [seed=2000] [thresholds=0.3,0.4,0.5,0.6,0.7] [min_steps=1]
                       [max_steps=0,60,80] [write=true] [start_step=S] [reset=false] [learned_max_steps=N] [threads=1]

(any :class:`SelectConfig` key) scores the policy ``MODELS/policy/<skill>`` and writes the grid, the per-config
normalised improvement and the selected rule to ``MODELS/policy/<skill>/select.json`` (resumable per config).
``pasta pipeline`` runs it as its ``select`` stage, with ``write=true``, for the policies of the skills whose
plugin lists ``select`` in its ``training_defaults`` (built-ins: cut and roll).

(``max_steps`` 0: no cap of the policy's own, only the skill's step limit; ``write=true`` stores the selected
rule in the checkpoint's ``model.json`` under ``config.controller``, which
:meth:`~pasta.policy.learned.LearnedPolicy.load` uses as its defaults.)
"""

from __future__ import annotations

import json
import sys
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pasta.core import Controller, SkillObservation, Stop
from pasta.core.errors import ConfigError
from pasta.core.files import append_text, write_json, write_text
from pasta.core.metrics import emd, normalized_improvement
from pasta.train.evaluate import SkillRunSettings

__all__ = ["RecordingController", "SelectConfig", "grid_table", "select_command", "select_config", "select_rule",
           "stop_index", "summary", "sweep", "train_command", "write_rule"]


def stop_index(probs: Sequence[float], actions: Sequence[np.ndarray], threshold: float, min_steps: int,
               max_steps: int = 0) -> int:
    """Env steps taken when the rule ``(threshold, min_steps)`` stops a rollout whose controller output
    done probability ``probs[i]`` and action ``actions[i]`` at its step ``i``: like
    :func:`~pasta.tasks.step.run_skill`, a done with a non-zero action is applied then ends the
    step, an all-zero one ends it without stepping; ``len(probs)`` when the rule never fires.
    ``max_steps`` > 0: the controller also reports done at its ``max_steps``-th action."""
    for i, (p, a) in enumerate(zip(probs, actions)):
        if (i + 1 >= min_steps and p > threshold) or 0 < max_steps <= i + 1:
            return i + 1 if np.any(np.clip(np.asarray(a, np.float32), -1.0, 1.0)) else i
    return len(probs)


class RecordingController(Controller):
    """Wraps a learned :class:`~pasta.policy.learned.PolicyController`: never reports done, records at
    each step the simulator state (before the step), the done probability and the action."""

    def __init__(self, inner: Any, sim: Any) -> None:
        self.inner, self.sim = inner, sim
        self.states: list[Any] = []
        self.probs: list[float] = []
        self.actions: list[np.ndarray] = []

    def reset(self, obs: SkillObservation) -> None:
        self.inner.reset(obs)
        self.states, self.probs, self.actions = [], [], []

    def approach_pose(self, *args: Any, **kwargs: Any) -> Any:
        """The wrapped controller's own start pose (a learned reset pose), if it has one."""
        own = getattr(self.inner, "approach_pose", None)
        return own(*args, **kwargs) if callable(own) else None

    def act(self, obs: SkillObservation) -> tuple[np.ndarray, Stop | None]:
        self.states.append(self.sim.get_state())
        action, _ = self.inner.act(obs)
        self.probs.append(float(self.inner.last_done_prob))
        self.actions.append(np.asarray(action, np.float32))
        return action, None  # never stops: every rule is scored afterwards


def sweep(sim: Any, skill: Any, configs: Sequence[Any], thresholds: Sequence[float], min_steps: Sequence[int],
          caps: Sequence[int] = (0,), *, max_steps: int | None = None, idle_steps: int = 10, emd_points: int = 500,
          verbose: bool = True) -> dict[str, Any]:
    """Score every rule ``(threshold, min_steps, cap)`` on every config with one rollout per config
    (``cap``: the controller's own ``max_steps``, 0 = none; ``max_steps``: the rollout's step limit,
    default the skill's).

    ``skill`` must carry its learned policy (``skill.policy()``). Returns ``{"rules": [[t, m, cap], ...],
    "ni": [[per-config NI for each rule], ...] (configs x rules), "steps": same shape}``."""
    from pasta.tasks.step import run_skill

    rules = [(float(t), int(m), int(c)) for c in caps for m in min_steps for t in thresholds]
    ni_rows, step_rows = [], []
    for cfg in configs:
        sim.set_state(cfg.state)
        piece = sim.observe().dough
        approach, expert, limit = cfg.expert(sim, skill)
        run_skill(sim, skill, expert, np.arange(len(piece)), None, approach=approach, max_steps=limit)
        goal = sim.observe().dough
        emd0 = emd(piece, goal, n=emd_points, seed=cfg.seed)
        sim.set_state(cfg.state)
        rec = RecordingController(skill.policy(), sim)
        run_skill(sim, skill, rec, np.arange(len(piece)), goal, max_steps=max_steps, idle_steps=0, park=False)
        final = sim.get_state()
        row_ni, row_steps, cache = [], [], {}
        for t, m, c in rules:
            k = stop_index(rec.probs, rec.actions, t, m, c)
            if k not in cache:
                sim.set_state(rec.states[k] if k < len(rec.states) else final)
                for _ in range(max(0, idle_steps)):
                    sim.step()
                cache[k] = normalized_improvement(emd0, emd(sim.observe().dough, goal, n=emd_points, seed=cfg.seed))
            row_ni.append(cache[k])
            row_steps.append(k)
        ni_rows.append(row_ni)
        step_rows.append(row_steps)
        if verbose:
            best = int(np.argmax(row_ni))
            print(f"  {skill.name} seed {cfg.seed}: {len(rec.probs)} steps recorded, NI {min(row_ni):.3f}..{max(row_ni):.3f}"
                  f" (best rule {rules[best]})", file=sys.stderr, flush=True)
    return {"rules": [list(r) for r in rules], "ni": ni_rows, "steps": step_rows}


def select_rule(result: dict[str, Any]) -> tuple[tuple[float, ...], float]:
    """The rule with the highest mean normalised improvement (ties: the first in ``result["rules"]``)
    and that mean."""
    means = np.asarray(result["ni"], np.float64).mean(0)
    best = int(np.argmax(means))
    return tuple(result["rules"][best]), float(means[best])


def write_rule(directory: str | Path, rule: dict[str, Any]) -> None:
    """Store ``rule`` (``done_threshold``, ``min_steps``, ``max_steps``) as the controller defaults of the
    policy checkpoint in ``directory`` (``model.json``: ``config.controller``)."""
    path = Path(directory) / "model.json"
    doc = json.loads(path.read_text())
    doc["config"]["controller"] = rule
    write_json(path, doc)


@dataclass
class SelectConfig(SkillRunSettings):
    """Settings of :func:`select_command` (``pasta train select`` and the pipeline's ``select`` stage).

    Attributes:
        n: validation configs.
        seed: base seed of their stream (2000: validation; never the test stream 1000).
        thresholds: comma-separated done thresholds to try.
        min_steps: comma-separated ``min_steps`` values.
        max_steps: comma-separated caps on the policy's own actions (0: none).
        start_step, reset, n_particles, obs_points, n_grid, max_particles: :class:`SkillRunSettings`;
            ``learned_max_steps`` limits the rollout (0: the skill's own, or the largest cap if larger).
        write: store the selected rule in the checkpoint's ``model.json`` (``config.controller``).
        threads: torch CPU threads (0: leave as is).
        progress: print a line per config (stderr).
    """

    n: int = 20
    seed: int = 2000
    thresholds: str = "0.3,0.4,0.5,0.6,0.7"
    min_steps: str = "1"
    max_steps: str = "0"
    write: bool = False
    threads: int = 1
    progress: bool = True

    def __post_init__(self) -> None:
        from pasta.config.validate import check_int, check_number, check_seed, check_threads
        from pasta.train.evaluate import MAX_CONFIGS

        super().__post_init__()
        check_int(self.n, "n", low=1, high=MAX_CONFIGS)
        check_seed(self.seed, "seed")
        check_threads(self.threads, "threads")
        thresholds, min_steps, caps = self.grid()
        for t in thresholds:
            check_number(t, "thresholds", low=0.0, high=1.0)
        for m in min_steps:
            check_int(m, "min_steps", low=0)
        for c in caps:
            check_int(c, "max_steps", low=0)

    def grid(self) -> tuple[list[float], list[int], list[int]]:
        """The thresholds, ``min_steps`` and caps as lists."""
        try:
            out = ([float(v) for v in str(self.thresholds).split(",") if v.strip()],
                   [int(v) for v in str(self.min_steps).split(",") if v.strip()],
                   [int(v) for v in str(self.max_steps).split(",") if v.strip()])
        except ValueError as exc:
            raise ConfigError(f"thresholds, min_steps and max_steps must be comma-separated numbers: {exc}") from None
        if not all(out):
            raise ConfigError("thresholds, min_steps and max_steps must each name at least one value")
        return out


#: per-config rows of an unfinished :func:`select_command` (JSON lines), removed when it finishes
PARTIAL = "select.partial.jsonl"
#: the result of :func:`select_command` in the policy directory
RESULT = "select.json"


def select_config(overrides: Mapping[str, Any] | None = None) -> SelectConfig:
    """:class:`SelectConfig` from ``key=value`` overrides (a typo fails with the closest valid key, a
    malformed grid with what is wrong)."""
    from pasta.config.overrides import build

    cfg = build(SelectConfig, dict(overrides or {}), command="pasta train select")
    cfg.grid()
    return cfg


def select_command(models: str | Path, skill: str, overrides: dict[str, Any] | None = None, *,
                   out: str | Path | None = None, sim: Any = None, resume: bool = True) -> dict[str, Any]:
    """Score every stopping rule of the grid on the validation configs and pick the best (see the module
    docstring); the policy is ``models/policy/<skill>``.

    Writes ``out`` when given (the pipeline: ``models/policy/<skill>/select.json``; the grid, per-config
    normalised improvement and steps, the selected rule) and, with ``write``, the rule into
    ``model.json``. With ``out``, each config's row is appended to ``select.partial.jsonl`` beside it as
    soon as it is scored, so an interrupted run resumes at the next config (``resume=False`` starts
    over); returns the result.
    ``sim``: a simulator to use (default: a new one with ``n_particles`` / ``obs_points``).
    """
    from pasta.train.loop import torch_threads

    cfg = select_config(overrides)
    with torch_threads(cfg.threads):
        return _select(models, skill, cfg, out=out, sim=sim, resume=resume)


def _select(models: str | Path, skill: str, cfg: SelectConfig, *, out: str | Path | None, sim: Any,
            resume: bool) -> dict[str, Any]:
    from pasta.plugins import get_plugins
    from pasta.policy import POLICY_DIR
    from pasta.train.evaluate import make_configs
    from pasta.policy.learned import load_policy

    thresholds, min_steps, caps = cfg.grid()
    directory = Path(models) / POLICY_DIR / skill
    out = Path(out) if out is not None else None
    sim = sim if sim is not None else cfg.make_sim()
    sk = get_plugins().skills.create(skill)
    load_policy(directory, sk, **cfg.policy_options())
    limit = max([cfg.learned_max_steps or int(getattr(sk, "max_steps", 50)), *caps])
    configs = make_configs(sk, sim, cfg.n, cfg.seed)
    partial = out.with_name(PARTIAL) if out is not None else None
    key = {"skill": skill, "config": {k: v for k, v in asdict(cfg).items() if k not in ("threads", "progress", "write")}}
    rows = _read_partial(partial, key) if resume and partial is not None else []
    if partial is not None and not rows:
        write_text(partial, json.dumps({"key": key}) + "\n")
    elif rows and cfg.progress:
        print(f"  {skill}: resuming after {len(rows)} of {cfg.n} configs ({partial})", file=sys.stderr, flush=True)
    for c in configs[len(rows):]:
        res = sweep(sim, sk, [c], thresholds, min_steps, caps, max_steps=limit, verbose=cfg.progress)
        row = {"seed": c.seed, "ni": res["ni"][0], "steps": res["steps"][0]}
        if partial is not None:
            append_text(partial, json.dumps(row) + "\n")
        rows.append(row)
    rules = [[float(t), int(m), int(c)] for c in caps for m in min_steps for t in thresholds]
    result = {"rules": rules, "ni": [r["ni"] for r in rows], "steps": [r["steps"] for r in rows]}
    (t, m, cap), best = select_rule(result)
    rule = {"done_threshold": t, "min_steps": m, "max_steps": cap}
    doc = {"skill": skill, "seed": cfg.seed, "n": cfg.n, "models": str(models), "policy": str(directory),
           "settings": key["config"],
           "selected": {**rule, "mean_ni": best}, **result}
    if out is not None:
        write_json(out, doc, indent=1)
    if partial is not None:  # (set exactly when out is)
        partial.unlink(missing_ok=True)
    if cfg.write:
        write_rule(directory, rule)
    return doc


def _read_partial(path: Path, key: dict[str, Any]) -> list[dict[str, Any]]:
    """The rows of an unfinished run with the same settings (none when the file is missing or stale)."""
    try:
        lines = path.read_text().splitlines()
        if not lines or json.loads(lines[0]).get("key") != json.loads(json.dumps(key)):
            return []
        return [json.loads(line) for line in lines[1:] if line.strip()]
    except (OSError, json.JSONDecodeError, AttributeError):
        return []


def grid_table(doc: dict[str, Any]) -> str:
    """Markdown table of the mean normalised improvement of every rule in a :func:`select_command` result."""
    rules, means = doc["rules"], np.asarray(doc["ni"]).mean(0)
    thresholds = list(dict.fromkeys(r[0] for r in rules))
    lines = [f"| {doc['skill']}: max_steps, min_steps \\ done_threshold | " + " | ".join(f"{t:g}" for t in thresholds) + " |",
             "|---" * (len(thresholds) + 1) + "|"]
    for j in range(len(means) // len(thresholds)):
        _, m, c = rules[j * len(thresholds)]
        lines.append(f"| {c or '-'}, {m} | " + " | ".join(f"{means[j * len(thresholds) + i]:.3f}" for i in range(len(thresholds))) + " |")
    return "\n".join(lines)


def train_command(out: str | Path, overrides: dict[str, Any] | None = None) -> dict[str, Any]:
    """``pasta train select out=MODELS skill=NAME [key=value ...]`` as a function: :func:`select_command` on the
    policy ``MODELS/policy/<skill>``, its result in ``select.json`` beside it; returns that result."""
    from pasta.policy import POLICY_DIR

    pairs = dict(overrides or {})
    skill = pairs.pop("skill", "")
    if not skill:
        raise ConfigError("`pasta train select` needs skill=NAME (the policy in OUT/policy/NAME)")
    return select_command(out, skill, pairs, out=Path(out) / POLICY_DIR / skill / RESULT)


def summary(doc: dict[str, Any]) -> str:
    """The grid table and the selected rule of a :func:`select_command` result, as ``pasta train select`` prints them."""
    sel = doc["selected"]
    lines = [grid_table(doc), f"selected on seed={doc['seed']}: done_threshold={sel['done_threshold']:g} "
             f"min_steps={sel['min_steps']} max_steps={sel['max_steps']} (mean NI {sel['mean_ni']:.3f})"]
    if doc["settings"].get("write"):
        lines.append(f"wrote the rule to {Path(doc['policy']) / 'model.json'} (config.controller)")
    return "\n".join(lines)
