"""``pasta train MODULE [key=value ...]``: train one learned module, choose a policy's stopping rule, or
evaluate the policies on held-out single-skill configs."""

from __future__ import annotations

import argparse
import json
from typing import Any

from pasta.core.errors import ConfigError

HELP = ("train the VAE, a skill's feasibility, the cost model, a skill's policy or its reset pose on "
        "demonstrations, choose a policy's stopping rule, or evaluate the policies (data=DIR out=MODELS_DIR "
        "[key=value ...])")

EPILOG = """examples:
  pasta train vae data=demos out=models                  # writes models/vae
  pasta train vae data=demos out=models/flat flat=true   # whole-scene VAE (Flat 3D), models/flat/vae
  pasta train feasibility data=demos out=models skill=cut  # models/feasibility/cut (uses models/vae)
  pasta train cost data=demos out=models epochs=80       # models/cost
  pasta train policy data=demos out=models skill=cut     # models/policy/cut (behaviour cloning)
  pasta train reset data=demos out=models skill=cut target=skill   # models/policy/cut/reset.* (learned start pose)
  pasta train select out=models skill=cut write=true     # stopping rule on validation configs (seed 2000)
                                                         #   -> models/policy/cut/select.json (+ model.json)
  pasta train evaluate models=models n=20 seed=1000      # policies vs heuristic vs expert on test configs
common keys: epochs batch_size lr seed resume progress threads val_fraction stride; see docs/learning.md
(reset, select, evaluate: docs/policies.md)"""

MODULES = ("vae", "feasibility", "cost", "policy", "reset", "select", "evaluate")
#: what each module needs besides its own keys (evaluate reads models=, default the shipped weights)
_REQUIRED = {"select": ("out",), "evaluate": ()}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = EPILOG
    parser.add_argument("module", choices=MODULES, help="what to train (or select, or evaluate)")
    parser.add_argument("overrides", nargs="*", metavar="key=value",
                        help="data=DIR and out=DIR (select: out=DIR; evaluate: neither)")


def run(args: argparse.Namespace) -> int:
    from pasta.config.overrides import split_overrides

    pairs = split_overrides(args.overrides)
    check_arguments(args.module, pairs)  # every key and value, before any data is read or a model trained
    if args.module == "evaluate":
        from pasta.train.evaluate import evaluate_command, table

        print(table(evaluate_command(pairs)))
        return 0
    if args.module == "select":
        from pasta.train.select import summary, train_command

        print(summary(train_command(pairs.pop("out"), pairs)))
        return 0
    data, out = pairs.pop("data"), pairs.pop("out")
    if args.module == "policy":
        from pasta.train.policy import train_command as policy_command

        metrics = policy_command(data, out, pairs)
    elif args.module == "reset":
        from pasta.train.reset import train_command as reset_command

        metrics = reset_command(data, out, pairs)
    else:
        from pasta.train.run import train

        metrics = train(args.module, data, out, pairs)
    print(json.dumps(metrics, indent=2))
    return 0


#: the modules whose ``skill=`` is a key of the command, not of the trainer's config
_SKILL_KEY = ("policy", "reset", "select")


def module_configs(module: str, pairs: dict[str, Any]) -> tuple:
    """The settings of ``pasta train MODULE`` (every key but its paths, :data:`_REQUIRED`), built by the
    trainer's own builder, so that each is checked (unknown key, type, range) as the trainer will see it."""
    values = {k: v for k, v in pairs.items() if k not in _REQUIRED.get(module, ("data", "out"))}
    if module in _SKILL_KEY:
        values.pop("skill", None)
    if module in ("vae", "feasibility", "cost"):
        from pasta.train.run import parse_overrides

        return tuple(parse_overrides(module, values))
    if module == "policy":
        from pasta.train.policy import policy_configs

        return policy_configs(values)
    if module == "reset":
        from pasta.train.reset import reset_configs

        return reset_configs(values)
    if module == "select":
        from pasta.train.select import select_config

        return (select_config(values),)
    from pasta.train.evaluate import evaluate_config

    return (evaluate_config(values),)


def check_arguments(module: str, pairs: dict[str, Any]) -> tuple:
    """Check every key of ``pasta train MODULE`` before any work: the trainer's settings
    (:func:`module_configs`), ``skill=`` (a registered skill), ``data=`` (a dataset holding that skill's
    demonstrations), ``out=`` (a writable models root) and the trained weights the module starts from (the
    VAE of feasibility and cost, the policy of select). Returns the built configs."""
    from pasta.config.validate import check_output_dir

    required = _REQUIRED.get(module, ("data", "out"))
    missing = [k for k in required if not str(pairs.get(k, "")).strip()]
    if missing:
        raise ConfigError(f"`pasta train {module}` needs {' and '.join(k + '=DIR' for k in missing)}")
    configs = module_configs(module, pairs)
    skill = str(getattr(configs[-1], "skill", "") if module == "feasibility" else pairs.get("skill", "")).strip()
    if module in (*_SKILL_KEY, "feasibility"):
        if not skill:
            raise ConfigError(f"`pasta train {module}` needs skill=NAME (a registered skill)")
        from pasta.plugins import get_plugins

        get_plugins().skills.info(skill)  # an unknown name lists the registered skills
    if "out" in required:
        out = check_output_dir(pairs["out"], "out")
    if "data" in required:
        _check_dataset(pairs["data"], skill if module != "cost" and module != "vae" else "")
    if module in ("feasibility", "cost"):
        from pathlib import Path

        from pasta.io.checkpoint import checkpoint_exists
        from pasta.nn import VAE_DIR

        vae = Path(configs[-1].vae or out / VAE_DIR)
        if not checkpoint_exists(vae):
            raise ConfigError(f"`pasta train {module}` encodes with a trained VAE and there is none in {vae}: train it "
                              f"first (`pasta train vae data=DIR out={out}`{' flat=true' if configs[-1].flat else ''}) "
                              "or give vae=DIR")
    if module == "select":
        from pasta.io.checkpoint import checkpoint_exists
        from pasta.policy import POLICY_DIR

        if not checkpoint_exists(out / POLICY_DIR / skill):
            raise ConfigError(f"out={pairs['out']}: no trained policy of {skill} in {out / POLICY_DIR / skill}; "
                              f"train it first (`pasta train policy skill={skill} data=DIR out={pairs['out']}`)")
    return configs


def _check_dataset(data: str, skill: str) -> None:
    """``data=``: a dataset directory (``manifest.json``) with demonstrations (of ``skill`` when given)."""
    from pasta.config.validate import check_input_dir
    from pasta.core.errors import InputError
    from pasta.demos.data import demo_paths

    check_input_dir(data, "data")
    try:
        found = demo_paths(data, [skill] if skill else None)
    except InputError as exc:
        raise ConfigError(f"data={data}: {exc}") from None
    if not found:
        which = f" of skill {skill}" if skill else ""
        raise ConfigError(f"data={data}: no demonstrations{which} there (<skill>/demo_00000.npz files); generate them "
                          f"with `pasta demos skill={skill or 'NAME'} out={data}`")
