"""``pasta train vae|feasibility|cost data=DIR out=DIR [key=value ...]``: train one learned module."""

from __future__ import annotations

import argparse
import json

from pasta.core.errors import ConfigError

HELP = "train the VAE, a skill's feasibility, the cost model or a skill's policy on demonstrations (data=DIR out=MODELS_DIR [key=value ...])"

EPILOG = """examples:
  pasta train vae data=demos out=models                  # writes models/vae
  pasta train vae data=demos out=models flat=true        # whole-scene VAE, models/flat_vae
  pasta train feasibility data=demos out=models skill=cut  # models/feasibility/cut (uses models/vae)
  pasta train cost data=demos out=models epochs=80       # models/cost
  pasta train policy data=demos out=models skill=cut     # models/policy/cut (behaviour cloning)
common keys: epochs batch_size lr seed resume progress val_fraction stride; see docs/learning.md"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = EPILOG
    parser.add_argument("module", choices=["vae", "feasibility", "cost", "policy"], help="what to train")
    parser.add_argument("overrides", nargs="*", metavar="key=value", help="data=DIR and out=DIR are required")


def run(args: argparse.Namespace) -> int:
    from pasta.config.overrides import split_overrides

    pairs = split_overrides(args.overrides)
    missing = [k for k in ("data", "out") if not pairs.get(k)]
    if missing:
        raise ConfigError(f"`pasta train {args.module}` needs {' and '.join(k + '=DIR' for k in missing)}")
    data, out = pairs.pop("data"), pairs.pop("out")
    if args.module == "policy":
        from pasta.train.policy import train_command

        metrics = train_command(data, out, pairs)
    else:
        from pasta.train.run import train

        metrics = train(args.module, data, out, pairs)
    print(json.dumps(metrics, indent=2))
    return 0
