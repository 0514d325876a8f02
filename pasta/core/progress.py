"""Progress of long work: reported by whoever does it, shown or logged by whoever listens.

A planner (or any long computation) calls :func:`report` as it goes; a caller that wants to show or log the
progress wraps the call in :func:`listening`. Listeners nest (``pasta run`` draws a progress bar and its run
log records ``/planner/progress``); with nobody listening, :func:`report` is one context-variable lookup,
and :func:`active` lets a reporter skip computing what it would report.

Third-party planners report the same way: ``pasta.core.progress.report("optimise", it, iterations,
best_score=...)``.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass, field
from typing import Any

__all__ = ["Progress", "active", "listening", "report"]


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
