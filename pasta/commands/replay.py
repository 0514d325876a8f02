"""``pasta replay RUN.mcap``: the run-file tool of :mod:`pasta.io.replay`, registered as a subcommand."""

from pasta.io.replay import HELP, add_arguments, run

__all__ = ["HELP", "add_arguments", "run"]
