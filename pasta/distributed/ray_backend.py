"""The Ray backend: one Ray task per item, retried by the driver when its worker dies.

Every item is a ``ray.remote`` task (one CPU) that builds its worker's state once per Ray worker process
(:func:`pasta.distributed.worker_state`: a worker process that gets ten demos starts one simulator) and
returns the item's value; the driver gathers the values with ``ray.wait`` as they complete and is the
only process that writes files (a worker may run on another machine).

Retries are the driver's, not Ray's (``max_retries=0``): a task whose worker died (``WorkerCrashedError``,
a lost node, a lost result) is submitted again with ``attempt + 1`` until ``max_attempts``, with the
same warning and the same failure report as the local backend. An exception raised by a job is
returned as that item's error at once (it would repeat).

Deadlines (``deadline_s``): a task is a generator that reports ``begin`` when it runs and ``ready`` when
its worker has its state, before the item's result. So the driver knows which tasks run, not just wait
for a CPU (those have no deadline: on a busy cluster they may wait long), and starts an item's clock at
``ready``, as the local backend does (``init`` is not counted; it has its own limit,
``max(STARTUP_S, deadline_s)`` from ``begin``). ``ray.wait`` never blocks past the nearest deadline; an
overdue task is cancelled (``ray.cancel(force=True)``: Ray kills its worker, stopped or not) and costs one
attempt, then its item is submitted again or, after ``max_attempts``, reported as failed.

What travels to the workers: the job's functions by reference (pasta must be installed on every node,
in the same version), the setup (a small dict of settings), the driver's ``PASTA_*`` environment
variables (cache folders, test hooks). Model weights are read by the workers from the paths in the
setup (the shipped weights are inside the package); kernels compile once per node into its Taichi
offline cache. See docs/scaling.md.
"""

from __future__ import annotations

import atexit
import math
import os
import time
from collections import deque
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from typing import Any

from pasta.core.errors import ConfigError
from pasta.distributed import (RAY_INSTALL, STARTUP_S, BackendConfig, BackendError, Outcome, apply_env, attempts_error,
                               call_job, due_time, job_error, overdue_reason, run_test_hooks, seconds, shipped_env, wait_timeout,
                               warn, worker_state)

_STARTED: list[bool] = []  # whether this process started the Ray instance it uses (then it stops it at exit)


def import_ray() -> Any:
    """The ``ray`` module, or a one-line :class:`ConfigError` that says how to install it."""
    try:
        import ray
    except ImportError:
        raise ConfigError(f"backend=ray needs Ray, which is not installed: {RAY_INSTALL}") from None
    return ray


def ensure_ray(cfg: BackendConfig) -> Any:
    """Connect to Ray once per process: the cluster at ``cfg.address``, or a local instance started here."""
    ray = import_ray()
    if ray.is_initialized():
        return ray
    kwargs: dict[str, Any] = {"include_dashboard": False, "log_to_driver": True, "configure_logging": False}
    if cfg.address:
        _probe(cfg.address)
        kwargs["address"] = cfg.address
    else:
        kwargs["num_cpus"] = cfg.num_cpus or os.cpu_count() or 1
        kwargs["object_store_memory"] = int(cfg.object_store_mb) * 1_000_000
    tries = 1 if cfg.address else 2  # a local instance can miss Ray's 30 s startup limit on a loaded machine
    for attempt in range(1, tries + 1):
        try:
            ray.init(**kwargs)
            break
        except Exception as exc:  # noqa: BLE001 - Ray raises bare Exception for a startup timeout
            ray.shutdown()
            if attempt < tries:
                continue
            where = f"ray.address={cfg.address}" if cfg.address else "a local Ray instance"
            first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
            raise BackendError(f"could not start or reach {where}: {first}") from None
    if not cfg.address:
        _STARTED.append(True)
        atexit.register(ray.shutdown)
    return ray


def _probe(address: str, timeout_s: float = 5.0) -> None:
    """Fail fast when nothing listens at ``HOST:PORT`` (``ray.init`` would retry for minutes)."""
    import socket

    if address == "auto":
        return  # Ray finds the cluster started on this machine, or says at once that there is none
    host, _, port = address.removeprefix("ray://").rpartition(":")
    if not host or not port.isdigit():
        raise ConfigError(f"ray.address={address}: must be auto, HOST:PORT or ray://HOST:PORT")
    try:
        socket.create_connection((host, int(port)), timeout=timeout_s).close()
    except OSError as exc:
        raise BackendError(f"could not reach ray.address={address}: {exc.strerror or exc} (is `ray start --head` "
                           "running there?)") from None


def _task(init: Callable, job: Callable, setup: Any, item: Any, attempt: int, env: dict,
          hooks: Mapping[str, str]) -> Iterator[tuple[str, Any]]:
    """The body of every Ray task, a generator: ``("begin", None)`` as it starts, ``("ready", None)`` once its
    worker has its state (the item's deadline counts from there), then ``("done", value)`` or
    ``("error", traceback)``; ``("start_error", traceback)`` instead of ``ready`` when ``init`` fails."""
    import traceback

    yield "begin", None
    apply_env(env)
    try:
        state = worker_state(init, setup)
    except Exception:  # noqa: BLE001 - the driver stops the run: every item would fail the same way
        yield "start_error", traceback.format_exc()
        return
    yield "ready", None
    run_test_hooks(hooks, item, attempt)
    yield call_job(job, state, item, attempt)


def _death_errors(ray: Any) -> tuple[type[BaseException], ...]:
    """Ray's exceptions for a task whose worker, node or result was lost (not the job's own exception)."""
    ex = ray.exceptions
    names = ("WorkerCrashedError", "NodeDiedError", "ObjectLostError", "OwnerDiedError", "LocalRayletDiedError",
             "RaySystemError", "TaskUnschedulableError", "OutOfMemoryError")
    return tuple(getattr(ex, n) for n in names if isinstance(getattr(ex, n, None), type))


def run_ray(init: Callable, job: Callable, setup: Any, items: list, *, cfg: BackendConfig, workers: int,
            max_attempts: int, label: str, prog: str, deadline_s: float = 0.0,
            hooks: Mapping[str, str] | None = None) -> Iterator[Outcome]:
    """Run the items as Ray tasks, at most ``workers`` in flight (0: the cluster's CPUs); an iterator of
    outcomes. ``deadline_s``: seconds a task may spend on its item (0: no deadline; see the module
    docstring). Connects to Ray now (an unreachable cluster fails here, before the first result)."""
    ray = ensure_ray(cfg)
    return _outcomes(ray, init, job, setup, items, workers=workers, max_attempts=max_attempts, label=label,
                     prog=prog, deadline_s=deadline_s, hooks=dict(hooks or {}))


@dataclass(eq=False)
class _Task:
    """A task in flight: its item, and when it passes its deadline (``inf`` while it waits for a CPU)."""

    item: Any
    due: float = math.inf
    starting: bool = False  # it reported begin, not ready yet: its worker is building its state


def _outcomes(ray: Any, init: Callable, job: Callable, setup: Any, items: list, *, workers: int, max_attempts: int,
              label: str, prog: str, deadline_s: float, hooks: dict, poll_s: float = 1.0) -> Iterator[Outcome]:
    remote = ray.remote(num_cpus=1, max_retries=0, num_returns="streaming")(_task)
    env = shipped_env()
    deaths = _death_errors(ray)
    limit = workers if workers > 0 else max(1, int(ray.cluster_resources().get("CPU", 1)))
    setup_ref = ray.put(setup)  # sent once, not with every task
    startup_s = max(STARTUP_S, deadline_s) if deadline_s > 0 else 0.0
    queue: deque = deque(items)
    attempts: dict[Any, int] = {}
    reasons: dict[Any, list[str]] = {}  # item -> how each of its attempts ended without a result
    inflight: dict[Any, _Task] = {}  # ObjectRefGenerator -> its task

    def submit() -> None:
        while queue and len(inflight) < limit:
            item = queue.popleft()
            attempts[item] = attempts.get(item, 0) + 1
            inflight[remote.remote(init, job, setup_ref, item, attempts[item], env, hooks)] = _Task(item)

    def lost(task: _Task, reason: str, warning: str) -> Outcome | None:
        """An attempt that ended without a result: the item goes back to the queue, or its failure."""
        item = task.item
        reasons.setdefault(item, []).append(reason)
        if attempts[item] >= max_attempts:
            return Outcome(item, error=attempts_error(reasons[item]), attempts=attempts[item])
        warn(prog, f"{warning}; {label} {item} goes back to the queue")
        queue.appendleft(item)
        return None

    def receive(gen: Any) -> Outcome | None:
        """The task's next message: its start (the clock is set), or its end (``gen`` leaves ``inflight``)."""
        task = inflight[gen]
        try:
            status, value = ray.get(next(gen))
        except deaths as exc:
            del inflight[gen]
            why = type(exc).__name__
            return lost(task, f"its Ray worker died ({why})", f"Ray worker died ({why}) on {label} {task.item}")
        except ray.exceptions.RayTaskError as exc:  # outside the job (e.g. unpickling its arguments)
            del inflight[gen]
            return Outcome(task.item, error=f"raised an exception:\n{exc}", attempts=attempts[task.item])
        if status in ("begin", "ready"):
            task.starting = status == "begin"
            task.due = due_time(startup_s if task.starting else deadline_s)
            return None
        del inflight[gen]
        if status == "start_error":
            raise BackendError(f"a Ray worker could not start:\n{value}")
        if status == "error":
            return Outcome(task.item, error=job_error(value), attempts=attempts[task.item])
        return Outcome(task.item, value=value, attempts=attempts[task.item])

    def give_up(gen: Any) -> Outcome | None:
        """Cancel an overdue task (Ray kills its worker, even a stopped one) and count the attempt."""
        task = inflight.pop(gen)
        _cancel(ray, gen)
        if task.starting:
            why = f"did not start within {seconds(startup_s)} s"
            return lost(task, f"its Ray worker {why}",
                        f"the Ray worker for {label} {task.item} {why}; its task was cancelled")
        return lost(task, overdue_reason(deadline_s), f"the Ray task of {label} {task.item} exceeded the deadline of "
                    f"{seconds(deadline_s)} s and was cancelled")

    try:
        submit()
        while inflight:
            # never wait past the nearest deadline (a stopped worker sends nothing and does not die), nor
            # longer than poll_s: Python's signal handlers (Ctrl-C) run only between Ray's waits
            timeout = wait_timeout((task.due for task in inflight.values()), poll_s)
            ready, _ = ray.wait(list(inflight), num_returns=1, timeout=timeout)
            for gen in ready:
                outcome = receive(gen)
                if outcome is not None:
                    yield outcome
            for gen in [g for g, task in inflight.items() if task.due <= time.monotonic()]:
                outcome = give_up(gen)
                if outcome is not None:
                    yield outcome
            submit()
    finally:
        for gen in inflight:  # an error or Ctrl-C in the driver: the rest is not wanted
            _cancel(ray, gen)


def _cancel(ray: Any, gen: Any) -> None:
    try:
        ray.cancel(gen, force=True)
    except Exception:  # noqa: BLE001 - best effort; the instance goes at exit
        pass
