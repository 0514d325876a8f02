"""Subcommands of the ``pasta`` CLI, one module each (see :mod:`pasta.cli`)."""
