"""Progress of the planner on the terminal: a bar with the stage, the iterations done, the candidates left,
the best score so far and an ETA (:mod:`pasta.core.progress`). Shown only when stderr is a terminal, so a
log file or a pipe gets the command's result lines and nothing else."""

from __future__ import annotations

import sys
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from pasta.core import progress


@contextmanager
def planning_bar(enabled: bool | None = None) -> Iterator[None]:
    """Draw the planner's progress while the block runs (``enabled``: default, stderr is a terminal)."""
    if enabled is None:
        enabled = sys.stderr.isatty()
    if not enabled:
        yield
        return
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

    columns = (TextColumn("planning: {task.description}"), BarColumn(), MofNCompleteColumn(), TextColumn("{task.fields[info]}"),
               TimeElapsedColumn(), TimeRemainingColumn())
    with Progress(*columns, console=Console(stderr=True), transient=True) as bar:
        tasks: dict[str, Any] = {}

        def show(event: progress.Progress) -> None:
            if event.stage not in tasks:
                tasks[event.stage] = bar.add_task(event.stage, total=event.total, info="")
            best = event.info.get("best_score")
            info = f"{event.info.get('samples', '?')} candidates" + (f", best {best:.3f}" if isinstance(best, float) else "")
            bar.update(tasks[event.stage], completed=event.done, total=event.total, info=info)

        with progress.listening(show):
            yield
