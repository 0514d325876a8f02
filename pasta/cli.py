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
from typing import NoReturn

import pasta.commands
from pasta.core.errors import PastaError
from pasta.core.files import OutputLock


class _Parser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line, ``pasta CMD: error: ...``, as every other error
    of the command line (exit code 2); ``pasta CMD --help`` shows the usage."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {one_line(message)} (`{self.prog} --help` shows the usage)\n")


#: the one style of every command, stated in ``pasta --help``
STYLE = """one style for every command:
  settings   key=value, e.g. `pasta run task=crs horizon=3`; a later item of the same key wins; an unknown
             key is one error line naming the closest valid key. `pasta config [key=value ...]` lists
             the run config that plan, run and eval read; each command's --help lists its own keys
  modes      --flags, e.g. `pasta replay RUN.mcap --verify`, `pasta plugins --json`; anywhere on the line
  threads=N  on every command that computes (plan, run, eval, demos, train, pipeline, replay): its CPU
             threads (torch's, or the simulator's where the simulator computes); 0: the library's default
  progress   bars with an ETA (planning: iterations and candidates) on stderr when it is a terminal; a
             pipe or a log file gets the result lines only
exit codes: 0 ok, 1 the work failed, 2 usage (a bad command, key or value), 3 a plan flagged unreachable"""


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="pasta", description="Plan and execute multi-tool dough manipulation (PASTA).",
                     epilog=STYLE, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--version", action="version", version=f"pasta {pasta.__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for info in sorted(pkgutil.iter_modules(pasta.commands.__path__), key=lambda m: m.name):
        if info.name.startswith("_"):
            continue
        module = importlib.import_module(f"pasta.commands.{info.name}")
        cmd = sub.add_parser(info.name.replace("_", "-"), help=module.HELP, description=module.HELP)
        module.add_arguments(cmd)
        cmd.set_defaults(handler=module.run)
    parser.set_defaults(commands=sub.choices)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args, extra = build_parser().parse_known_args(argv)
    if extra and isinstance(getattr(args, "overrides", None), list):
        # argparse fills a `key=value ...` positional from the items before the first --flag only; the
        # settings after a flag are the command's settings all the same (modes go anywhere), in their order
        args.overrides += [item for item in extra if not item.startswith("-")]
        extra = [item for item in extra if item.startswith("-")]
    if extra:  # named by the command's own parser: `pasta run: error: unrecognized arguments: ...`
        args.commands[args.command].error(f"unrecognized arguments: {' '.join(extra)}")
    with warnings.catch_warnings():
        _plugin_warnings_as_lines()
        try:
            return int(args.handler(args) or 0)
        except PastaError as exc:  # a usage error (exit 2), or a plugin that failed at work (its exit_code, 1)
            code = int(getattr(exc, "exit_code", 2))
            print(f"pasta {args.command}: error: {one_line(str(exc)) if code == 2 else exc}", file=sys.stderr)
            return code
        finally:
            OutputLock.release_all()  # the outputs this command claimed (pasta.core.files)


def one_line(text: str) -> str:
    """``text`` with its line breaks and other unprintable characters escaped (``\\n``, ``\\x1e``), so that an
    error message that quotes a value given on the command line stays one line."""
    return "".join(c if c.isprintable() else c.encode("unicode_escape").decode("ascii") for c in text)


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
