"""``pasta train MODULE [key=value ...]``: train one learned module, choose a policy's stopping rule, or
evaluate the policies on held-out single-skill configs."""

from __future__ import annotations

import argparse
import json

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
    required = _REQUIRED.get(args.module, ("data", "out"))
    missing = [k for k in required if not pairs.get(k)]
    if missing:
        raise ConfigError(f"`pasta train {args.module}` needs {' and '.join(k + '=DIR' for k in missing)}")
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
