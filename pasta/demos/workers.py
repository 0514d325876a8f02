"""Worker processes of ``pasta demos``: a dead worker is noticed, its demo re-queued, workers die with the parent.

The parent talks to each worker over its own pipe, one demo at a time, and waits on the pipes *and* the
process sentinels (:func:`multiprocessing.connection.wait`), so a worker killed by a signal or the OOM
killer is seen at once, never waited for. (A shared ``multiprocessing.Queue`` is not used: a worker
killed while holding the queue's lock would block the others.)

- A worker that dies while generating demo ``i`` gets a replacement and ``i`` goes back to the front of
  the queue; after ``max_attempts`` deaths on the same demo, ``i`` is reported as failed with its seed and
  the others go on. A Python exception inside a demo is reported at once (it would repeat).
- Workers die with the parent: on Linux ``prctl(PR_SET_PDEATHSIG, SIGKILL)`` (the kernel kills the worker
  when its parent dies), elsewhere (and as a second guard) a watchdog thread that exits when the parent
  pid changes. Workers ignore Ctrl-C; the parent stops them.

A test hook (environment, read by the workers): ``PASTA_DEMOS_TEST_KILL=K`` makes a worker SIGKILL itself
when it starts demo ``K`` (every attempt), ``K@1`` on the first attempt only.
"""

from __future__ import annotations

import os
import signal
import sys
import threading
import time
import traceback
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pasta.core.errors import PastaError

#: attempts per demo before it is reported as failed (a worker death costs one attempt)
MAX_ATTEMPTS = 2
#: worker deaths outside any demo (e.g. while the simulator starts) that end the run
MAX_IDLE_DEATHS = 3
TEST_KILL_ENV = "PASTA_DEMOS_TEST_KILL"
_WATCHDOG_PERIOD_S = 0.5


class DemoWorkerError(PastaError, RuntimeError):
    """Demo workers could not start, or some demos could not be made (the message names them and their seeds)."""


@dataclass
class _Worker:
    proc: Any
    conn: Any
    ready: bool = False
    current: int | None = None  # the demo it is generating
    messages: list[tuple] = field(default_factory=list)


def die_with_parent(parent_pid: int) -> None:
    """Make this process exit when ``parent_pid`` is no longer its parent (the parent died)."""
    if sys.platform.startswith("linux"):
        try:
            import ctypes

            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(1, int(signal.SIGKILL), 0, 0, 0)  # PR_SET_PDEATHSIG = 1
        except (OSError, AttributeError):
            pass  # the watchdog below still covers it
    if os.getppid() != parent_pid:  # the parent died before the line above ran
        os._exit(1)

    def watch() -> None:
        while os.getppid() == parent_pid:
            time.sleep(_WATCHDOG_PERIOD_S)
        os._exit(1)  # no cleanup: the parent is gone, nobody reads our results

    threading.Thread(target=watch, name="pasta-parent-watchdog", daemon=True).start()


def _test_kill(index: int, attempt: int) -> None:
    spec = os.environ.get(TEST_KILL_ENV, "")
    if not spec:
        return
    target, _, only = spec.partition("@")
    if int(target) == index and (not only or int(only) == attempt):
        os.kill(os.getpid(), signal.SIGKILL)


def worker_main(cfg_dict: dict, conn: Any, parent_pid: int) -> None:
    """Body of a worker: build the simulator, then generate the demos the parent sends, one at a time.

    Messages to the parent: ``("ready",)``, ``("done", i, steps, seconds)``, ``("error", i, traceback)``,
    ``("start_error", traceback)``. From the parent: ``(i, attempt)`` or ``None`` (stop).
    """
    die_with_parent(parent_pid)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C goes to the parent, which stops us
    from pasta.demos.generate import DemoConfig, DemoWriter

    try:
        writer = DemoWriter(DemoConfig(**cfg_dict))
    except BaseException:  # noqa: BLE001 - report anything to the parent
        conn.send(("start_error", traceback.format_exc()))
        return
    conn.send(("ready",))
    while True:
        try:
            task = conn.recv()
        except (EOFError, OSError):  # the parent closed the pipe or died
            return
        if task is None:
            return
        index, attempt = task
        _test_kill(index, attempt)
        try:
            steps, secs = writer.write(index)
        except Exception:  # noqa: BLE001 - reported with the demo's index
            conn.send(("error", index, traceback.format_exc()))
        else:
            conn.send(("done", index, steps, secs))


def _death(proc: Any) -> str:
    code = proc.exitcode
    if code is not None and code < 0:
        try:
            return f"killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exited with code {code}"


def run_workers(
    cfg_dict: dict,
    todo: list[int],
    n_workers: int,
    on_done: Callable[[int, int, float], None],
    *,
    tmp_dir: Path | None = None,
    max_attempts: int = MAX_ATTEMPTS,
    poll_s: float = 1.0,
) -> dict[int, str]:
    """Generate demos ``todo`` in ``n_workers`` spawned processes; returns ``{index: why}`` for the demos
    that could not be made (empty on success). ``on_done(index, steps, seconds)`` is called in the parent
    for every finished demo. ``tmp_dir``: where a killed worker may have left a ``.demo_*.tmp`` file.

    Raises :class:`DemoWorkerError` when workers cannot start at all (the first worker's error, or
    ``MAX_IDLE_DEATHS`` deaths outside any demo).
    """
    import multiprocessing as mp
    from multiprocessing.connection import wait

    ctx = mp.get_context("spawn")
    queue: deque[int] = deque(todo)
    attempts: dict[int, int] = {}
    failures: dict[int, str] = {}
    workers: list[_Worker] = []
    idle_deaths = 0

    def spawn() -> None:
        here, there = ctx.Pipe(duplex=True)
        proc = ctx.Process(target=worker_main, args=(cfg_dict, there, os.getpid()), daemon=True,
                           name=f"pasta-demos-{len(workers)}")
        proc.start()
        there.close()  # only the worker holds its end: its death closes the pipe
        workers.append(_Worker(proc, here))

    def busy() -> bool:
        return any(w.current is not None for w in workers)

    def handle(w: _Worker, msg: tuple) -> None:
        kind = msg[0]
        if kind == "ready":
            w.ready = True
        elif kind == "done":
            w.current = None
            on_done(int(msg[1]), int(msg[2]), float(msg[3]))
        elif kind == "error":
            w.current = None
            failures[int(msg[1])] = f"raised an exception:\n{msg[2]}"
        elif kind == "start_error":
            raise DemoWorkerError(f"a demo worker could not start:\n{msg[1]}")

    def drain(w: _Worker) -> None:
        try:
            while w.conn.poll():
                handle(w, w.conn.recv())
        except (EOFError, OSError):
            pass

    try:
        for _ in range(min(n_workers, len(queue))):
            spawn()
        while queue or busy():
            for w in workers:  # hand out work to idle workers
                if w.ready and w.current is None and queue and w.proc.exitcode is None:
                    index = queue.popleft()
                    attempts[index] = attempts.get(index, 0) + 1
                    try:
                        w.conn.send((index, attempts[index]))
                        w.current = index
                    except (BrokenPipeError, OSError):  # died just now: the sentinel says so below
                        attempts[index] -= 1
                        queue.appendleft(index)
            ready = set(wait([w.conn for w in workers] + [w.proc.sentinel for w in workers], timeout=poll_s))
            for w in list(workers):
                if w.conn in ready:
                    drain(w)
                if w.proc.sentinel in ready or w.proc.exitcode is not None:
                    w.proc.join()
                    drain(w)  # results sent just before it died still count
                    workers.remove(w)
                    w.conn.close()
                    why = _death(w.proc)
                    if w.current is not None:
                        index = w.current
                        _remove_tmp(tmp_dir, index, w.proc.pid)
                        if attempts[index] >= max_attempts:
                            failures[index] = f"its worker was {why} on each of {attempts[index]} attempts"
                        else:
                            print(f"pasta demos: warning: worker {w.proc.pid} {why} on demo {index}; "
                                  f"demo {index} goes back to the queue", file=sys.stderr)
                            queue.appendleft(index)
                    else:
                        idle_deaths += 1
                        if idle_deaths >= MAX_IDLE_DEATHS:
                            where = "while starting" if not w.ready else "between demos"
                            raise DemoWorkerError(f"demo workers keep dying outside any demo (the last one {why} "
                                                  f"{where}); {len(queue)} demos were not made")
            need = min(n_workers, len(queue) + sum(w.current is not None for w in workers))
            while len(workers) < need:  # replacements for dead workers
                spawn()
    finally:
        _stop(workers)
    return failures


def _remove_tmp(tmp_dir: Path | None, index: int, pid: int | None) -> None:
    """The half-written file of a killed worker (:func:`pasta.tasks.npz.write_npz` names it by pid)."""
    if tmp_dir is not None and pid is not None:
        (tmp_dir / f".demo_{index:05d}.npz.{pid}.tmp").unlink(missing_ok=True)


def _stop(workers: list[_Worker]) -> None:
    for w in workers:
        try:
            w.conn.send(None)
        except (BrokenPipeError, OSError):
            pass
    deadline = time.monotonic() + 5.0
    for w in workers:
        w.proc.join(timeout=max(0.0, deadline - time.monotonic()))
        if w.proc.is_alive():  # mid-demo (an error or Ctrl-C in the parent): stop it now
            w.proc.terminate()
            w.proc.join(timeout=2.0)
            if w.proc.is_alive():
                w.proc.kill()
                w.proc.join()
        w.conn.close()
