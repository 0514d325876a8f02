"""Errors raised by pasta. Every message names the offending thing and, where possible, the fix."""

from __future__ import annotations

import difflib
from collections.abc import Iterable


class PastaError(Exception):
    """Base class of every error pasta raises on purpose."""


class InputError(PastaError, ValueError):
    """Bad user input: wrong shape, NaN, empty point cloud, out-of-range value."""


class ConfigError(PastaError, ValueError):
    """A configuration key or value is invalid."""


class PluginNotFoundError(PastaError, KeyError):
    """A plugin name is not registered. The message lists the registered names."""

    def __init__(self, kind: str, name: str, known: Iterable[str]) -> None:
        self.kind, self.name, self.known = kind, name, sorted(known)
        hint = did_you_mean(name, self.known)
        listing = ", ".join(self.known) if self.known else "(none registered)"
        super().__init__(f"unknown {kind} '{name}'{hint}; known {kind}s: {listing}")

    def __str__(self) -> str:  # KeyError would otherwise wrap the message in quotes
        return str(self.args[0])


class PluginValidationError(PastaError, TypeError):
    """A plugin was found but does not honour its contract (wrong base class, bad cardinality, ...)."""


class PluginRuntimeError(PastaError, RuntimeError):
    """A plugin failed while it worked (it raised, or returned what its contract does not allow). The message
    names the plugin and its distribution; the command line exits with code 1 (not a usage error)."""

    exit_code = 1


class MissingComponentError(PastaError, NotImplementedError):
    """A component a call needs is not available yet (untrained network, unimplemented hook)."""


class UnreachableGoalError(PastaError, ValueError):
    """The goal cannot be reached by any plan (e.g. it holds far more or far less dough than the observation);
    the command line exits with code 3, as for a plan flagged unreachable."""

    exit_code = 3


class CardinalityError(PastaError, ValueError):
    """No skill sequence within the horizon turns the observed entity count into the goal's."""


class SimulationError(PastaError, RuntimeError):
    """The simulator produced an invalid state."""


def did_you_mean(name: str, candidates: Iterable[str]) -> str:
    """Return ``"; did you mean 'x'?"`` for the closest candidate, or ``""`` when none is close."""
    close = difflib.get_close_matches(name, list(candidates), n=1, cutoff=0.6)
    return f"; did you mean '{close[0]}'?" if close else ""
