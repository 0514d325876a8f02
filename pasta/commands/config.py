"""``pasta config [key=value ...]``: print the resolved run configuration."""

from __future__ import annotations

import argparse

from pasta.config import load_config, to_yaml

HELP = "print the resolved configuration (YAML defaults + key=value overrides; planner=NAME swaps the planner section)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("overrides", nargs="*", metavar="key=value")


def run(args: argparse.Namespace) -> int:
    print(to_yaml(load_config(args.overrides)), end="")
    return 0
