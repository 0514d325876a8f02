"""Progress of the planner on the terminal: a bar with the stage, the iterations done, the candidates left,
the best score so far and an ETA (:mod:`pasta.core.progress`). Shown only when stderr is a terminal, so a
log file or a pipe gets the command's result lines and nothing else."""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from typing import Any

from pasta.core import progress


@contextmanager
def planning_bar(enabled: bool | None = None) -> Iterator[None]:
    """Draw the planner's progress while the block runs (``enabled``: default, stderr is a terminal)."""
    if enabled is None:
        enabled = progress.on_terminal()
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


def duration(seconds: float) -> str:
    """``seconds`` as ``45s``, ``3m20s`` or ``2h05m``."""
    total = max(0, int(round(seconds)))
    hours, rest = divmod(total, 3600)
    minutes, secs = divmod(rest, 60)
    if hours:
        return f"{hours}h{minutes:02d}m"
    return f"{minutes}m{secs:02d}s" if minutes else f"{secs}s"


def eta(wall_s: Sequence[float], remaining: int, workers: int = 1) -> str:
    """``ETA 3m20s``: the mean wall time of the finished items times the ``remaining`` ones, over the
    ``workers`` running at once; empty before the first finishes and after the last."""
    if not wall_s or remaining <= 0:
        return ""
    return f"ETA {duration(sum(wall_s) / len(wall_s) * remaining / max(1, workers))}"
