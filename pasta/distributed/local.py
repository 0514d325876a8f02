"""Local worker processes: a dead worker is noticed, its item re-queued, workers die with the parent.

The parent talks to each worker over its own pipe, one item at a time, and waits on the pipes *and* the
process sentinels (:func:`multiprocessing.connection.wait`), so a worker killed by a signal or the OOM
killer is seen at once, never waited for. (A shared ``multiprocessing.Queue`` is not used: a worker
killed while holding the queue's lock would block the others.)

- A worker that dies while working on item ``i`` gets a replacement and ``i`` goes back to the front of
  the queue; after ``max_attempts`` deaths on the same item, ``i`` is reported as failed and the others
  go on. A Python exception inside a job is reported at once (it would repeat).
- Deadlines (``deadline_s``): the parent notes when it hands a worker its item (the worker has reported
  ready, so its ``init`` is not counted) and never waits past the nearest deadline. A worker whose item
  passes it is SIGKILLed (which also ends a stopped process) and handled like a death: the item costs one
  attempt and goes back to the front of the queue, or is reported as failed after ``max_attempts``. A
  worker that has not reported ready within ``max(STARTUP_S, deadline_s)`` is killed too, a death outside
  any item (:data:`MAX_IDLE_DEATHS` of them end the run).
- Workers die with the parent: on Linux ``prctl(PR_SET_PDEATHSIG, SIGKILL)`` (the kernel kills the worker
  when its parent dies), elsewhere (and as a second guard) a watchdog thread that exits when the parent
  pid changes. Workers ignore Ctrl-C; the parent stops them.
- Workers only compute: results travel back over the pipe and the parent writes them.
"""

from __future__ import annotations

import math
import os
import signal
import sys
import threading
import time
import traceback
from collections import deque
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from typing import Any

from pasta.distributed import (STARTUP_S, BackendError, Outcome, apply_env, attempts_error, call_job, due_time,
                               job_error, overdue_reason, run_test_hooks, seconds, shipped_env, wait_timeout, warn,
                               worker_state)

#: worker deaths outside any item (e.g. while the simulator starts) that end the run
MAX_IDLE_DEATHS = 3
_WATCHDOG_PERIOD_S = 0.5


@dataclass(eq=False)
class _Worker:
    proc: Any
    conn: Any
    ready: bool = False
    current: Any = None  # the item it works on (while busy)
    busy: bool = False
    due: float = math.inf  # when its start or its item passes the deadline (inf: nothing is due)
    given_up: bool = False  # the parent killed it for passing a deadline


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


def worker_main(init: Callable, job: Callable, setup: Any, conn: Any, parent_pid: int, env: dict,
                hooks: Mapping[str, str]) -> None:
    """Body of a worker: ``init(setup)``, then run the items the parent sends, one at a time.

    Messages to the parent: ``("ready",)``, ``("done", item, value)``, ``("error", item, traceback)``,
    ``("start_error", traceback)``. From the parent: ``(item, attempt)`` or ``None`` (stop).
    """
    die_with_parent(parent_pid)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C goes to the parent, which stops us
    apply_env(env)
    try:
        state = worker_state(init, setup)
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
        item, attempt = task
        run_test_hooks(hooks, item, attempt)
        status, value = call_job(job, state, item, attempt)
        conn.send((status, item, value))


def death(proc: Any) -> str:
    code = proc.exitcode
    if code is not None and code < 0:
        try:
            return f"killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exited with code {code}"


def run_local(init: Callable, job: Callable, setup: Any, items: list, *, workers: int, max_attempts: int,
              label: str, prog: str, deadline_s: float = 0.0, hooks: Mapping[str, str] | None = None,
              poll_s: float = 1.0) -> Iterator[Outcome]:
    """Run the items in ``workers`` spawned processes; yield an :class:`Outcome` per item as it completes.

    ``deadline_s``: seconds a worker may spend on one item (0: no deadline; see the module docstring).

    Raises :class:`BackendError` when workers cannot start at all (the first worker's error, or
    :data:`MAX_IDLE_DEATHS` deaths outside any item).
    """
    import multiprocessing as mp
    from multiprocessing.connection import wait

    ctx = mp.get_context("spawn")
    queue: deque = deque(items)
    attempts: dict[Any, int] = {}
    reasons: dict[Any, list[str]] = {}  # item -> how each of its attempts ended without a result
    pool: list[_Worker] = []
    results: deque[Outcome] = deque()
    env = shipped_env()
    hooks = dict(hooks or {})
    startup_s = max(STARTUP_S, deadline_s) if deadline_s > 0 else 0.0
    idle_deaths = 0

    def spawn() -> None:
        here, there = ctx.Pipe(duplex=True)
        proc = ctx.Process(target=worker_main, args=(init, job, setup, there, os.getpid(), env, hooks), daemon=True,
                           name=f"pasta-worker-{len(pool)}")
        proc.start()
        there.close()  # only the worker holds its end: its death closes the pipe
        pool.append(_Worker(proc, here, due=due_time(startup_s)))

    def handle(w: _Worker, msg: tuple) -> None:
        kind = msg[0]
        if kind == "ready":
            w.ready, w.due = True, math.inf
        elif kind == "done":
            w.busy, w.current, w.due = False, None, math.inf
            results.append(Outcome(msg[1], value=msg[2], attempts=attempts.get(msg[1], 1)))
        elif kind == "error":
            w.busy, w.current, w.due = False, None, math.inf
            results.append(Outcome(msg[1], error=job_error(msg[2]), attempts=attempts.get(msg[1], 1)))
        elif kind == "start_error":
            raise BackendError(f"a worker could not start:\n{msg[1]}")

    def drain(w: _Worker) -> None:
        try:
            while w.conn.poll():
                handle(w, w.conn.recv())
        except (EOFError, OSError):
            pass

    def buried(w: _Worker) -> None:
        """A dead worker's item goes back to the queue, or is reported after its last attempt."""
        nonlocal idle_deaths
        why = death(w.proc)
        if w.busy:
            item = w.current
            reasons.setdefault(item, []).append(overdue_reason(deadline_s) if w.given_up else f"its worker was {why}")
            if attempts[item] >= max_attempts:
                results.append(Outcome(item, error=attempts_error(reasons[item]), attempts=attempts[item]))
                return
            what = (f"on {label} {item} exceeded the deadline of {seconds(deadline_s)} s and was killed" if w.given_up
                    else f"{why} on {label} {item}")
            warn(prog, f"worker {w.proc.pid} {what}; {label} {item} goes back to the queue")
            queue.appendleft(item)
            return
        if w.given_up and w.ready:
            return  # its result came in just before the kill: nothing was lost
        idle_deaths += 1
        if w.given_up:
            why = f"did not start within {seconds(startup_s)} s and was killed"
            warn(prog, f"worker {w.proc.pid} {why}; a new one starts")
        if idle_deaths >= MAX_IDLE_DEATHS:
            where = "while starting" if not w.ready else f"between {label}s"
            raise BackendError(f"workers keep dying outside any {label} (the last one {why} "
                               f"{where}); {len(queue)} {label}s were not run")

    try:
        for _ in range(min(workers, len(queue))):
            spawn()
        while queue or any(w.busy for w in pool) or results:
            while results:
                yield results.popleft()
            if not queue and not any(w.busy for w in pool):
                break
            for w in pool:  # hand out work to idle workers
                if w.ready and not w.busy and queue and w.proc.exitcode is None:
                    item = queue.popleft()
                    attempts[item] = attempts.get(item, 0) + 1
                    try:
                        w.conn.send((item, attempts[item]))
                        w.busy, w.current, w.due = True, item, due_time(deadline_s)
                    except (BrokenPipeError, OSError):  # died just now: the sentinel says so below
                        attempts[item] -= 1
                        queue.appendleft(item)
            # never wait past the nearest deadline: a stopped worker sends nothing and does not die
            timeout = wait_timeout((w.due for w in pool), poll_s)
            ready = set(wait([w.conn for w in pool] + [w.proc.sentinel for w in pool], timeout=timeout))
            for w in pool:
                if w.conn in ready:
                    drain(w)  # first: a result that came in time is not thrown away below
            for w in pool:
                if w.due <= time.monotonic() and w.proc.exitcode is None:
                    _give_up(w)
            for w in list(pool):
                if w.proc.sentinel in ready or w.proc.exitcode is not None:
                    w.proc.join()
                    drain(w)  # results sent just before it died still count
                    pool.remove(w)
                    w.conn.close()
                    buried(w)
            need = min(workers, len(queue) + sum(w.busy for w in pool))
            while len(pool) < need:  # replacements for dead workers
                spawn()
    finally:
        _stop(pool)


def _give_up(w: _Worker) -> None:
    """Kill a worker that passed its deadline (SIGKILL: a stopped or hung process cannot ignore it); the
    loop then handles it as a death."""
    w.given_up = True
    w.proc.kill()
    w.proc.join(timeout=10.0)


def _stop(pool: list[_Worker]) -> None:
    for w in pool:
        try:
            w.conn.send(None)
        except (BrokenPipeError, OSError):
            pass
    deadline = time.monotonic() + 5.0
    for w in pool:
        w.proc.join(timeout=max(0.0, deadline - time.monotonic()))
        if w.proc.is_alive():  # mid-item (an error or Ctrl-C in the parent): stop it now
            w.proc.terminate()
            w.proc.join(timeout=2.0)
            if w.proc.is_alive():
                w.proc.kill()
                w.proc.join()
        w.conn.close()
