"""Progress of long work: reported by whoever does it, shown or logged by whoever listens.

A planner (or any long computation) calls :func:`report` as it goes; a caller that wants to show or log the
progress wraps the call in :func:`listening`. Listeners nest (``pasta run`` draws a progress bar and its run
log records ``/planner/progress``); with nobody listening, :func:`report` is one context-variable lookup,
and :func:`active` lets a reporter skip computing what it would report.

Third-party planners report the same way: ``pasta.core.progress.report("optimise", it, iterations,
best_score=...)``.

Every progress bar pasta draws (planning, demonstrations, training) goes to stderr and only when
:func:`on_terminal` says so: a pipe or a log file gets the command's result lines and nothing else.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass, field
from typing import Any

__all__ = ["Progress", "active", "listening", "on_terminal", "report"]


@dataclass(frozen=True)
class Progress:
    """``done`` of ``total`` units of ``stage`` (e.g. optimiser iterations), with named figures in ``info``
    (``samples``, ``best_score``, ...)."""

    stage: str
    done: int
    total: int
    info: Mapping[str, Any] = field(default_factory=dict)


Listener = Callable[[Progress], None]
_listeners: ContextVar[tuple[Listener, ...]] = ContextVar("pasta_progress_listeners", default=())


def active() -> bool:
    """Whether anyone listens (a reporter may skip computing its figures when not)."""
    return bool(_listeners.get())


def report(stage: str, done: int, total: int, **info: Any) -> None:
    """Tell every listener that ``done`` of ``total`` units of ``stage`` are done."""
    listeners = _listeners.get()
    if listeners:
        event = Progress(stage, int(done), int(total), info)
        for listener in listeners:
            listener(event)


@contextmanager
def listening(listener: Listener) -> Iterator[None]:
    """Call ``listener(progress)`` for every :func:`report` made inside the block (in this thread or task)."""
    token = _listeners.set((*_listeners.get(), listener))
    try:
        yield
    finally:
        _listeners.reset(token)


def on_terminal(enabled: bool = True) -> bool:
    """Whether to draw a progress bar: ``enabled`` and stderr, where the bars go, is a terminal. Asked
    explicitly because rich's bar, on a stream that is not a terminal, still prints its last state once
    when it stops (a bar line in a log file)."""
    isatty = getattr(sys.stderr, "isatty", None)
    return bool(enabled) and callable(isatty) and bool(isatty())
