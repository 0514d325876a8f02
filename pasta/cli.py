"""The ``pasta`` command line. Each subcommand is a module of :mod:`pasta.commands` exposing
``HELP``, ``add_arguments(parser)`` and ``run(args) -> int``; adding a module adds a command.
"""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys
import warnings
from collections.abc import Sequence

import pasta.commands
from pasta.core.errors import PastaError
from pasta.core.files import OutputLock


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="pasta", description="Plan and execute multi-tool dough manipulation (PASTA).")
    parser.add_argument("--version", action="version", version=f"pasta {pasta.__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for info in sorted(pkgutil.iter_modules(pasta.commands.__path__), key=lambda m: m.name):
        if info.name.startswith("_"):
            continue
        module = importlib.import_module(f"pasta.commands.{info.name}")
        cmd = sub.add_parser(info.name.replace("_", "-"), help=module.HELP, description=module.HELP)
        module.add_arguments(cmd)
        cmd.set_defaults(handler=module.run)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    with warnings.catch_warnings():
        _plugin_warnings_as_lines()
        try:
            return int(args.handler(args) or 0)
        except PastaError as exc:  # a usage error (exit 2), or a plugin that failed at work (its exit_code, 1)
            print(f"pasta {args.command}: error: {exc}", file=sys.stderr)
            return int(getattr(exc, "exit_code", 2))
        finally:
            OutputLock.release_all()  # the outputs this command claimed (pasta.core.files)


def _plugin_warnings_as_lines() -> None:
    """Print plugin load failures as one ``warning: pasta plugin ...`` line each (not file:line plus source)."""
    from pasta.plugins import PluginLoadWarning

    shown = warnings.showwarning

    def show(message, category, filename, lineno, file=None, line=None):
        if issubclass(category, PluginLoadWarning):
            print(f"warning: {message}", file=sys.stderr)
        else:
            shown(message, category, filename, lineno, file, line)

    warnings.showwarning = show


if __name__ == "__main__":
    sys.exit(main())
