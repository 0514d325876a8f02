"""The Ray backend: one Ray task per item, retried by the driver when its worker dies.

Every item is a ``ray.remote`` task (one CPU) that builds its worker's state once per Ray worker process
(:func:`pasta.distributed.worker_state`: a worker process that gets ten demos starts one simulator) and
returns the item's value; the driver gathers the values with ``ray.wait`` as they complete and is the
only process that writes files (a worker may run on another machine).

Retries are the driver's, not Ray's (``max_retries=0``): a task whose worker died (``WorkerCrashedError``,
a lost node, a lost result) is submitted again with ``attempt + 1`` until ``max_attempts``, with the
same warning and the same failure report as the local backend. An exception raised by a job is
returned as that item's error at once (it would repeat).

What travels to the workers: the job's functions by reference (pasta must be installed on every node,
in the same version), the setup (a small dict of settings), the driver's ``PASTA_*`` environment
variables (cache folders, test hooks). Model weights are read by the workers from the paths in the
setup (the shipped weights are inside the package); kernels compile once per node into its Taichi
offline cache. See docs/scaling.md.
"""

from __future__ import annotations

import atexit
import os
from collections import deque
from collections.abc import Callable, Iterator
from typing import Any

from pasta.core.errors import ConfigError
from pasta.distributed import (RAY_INSTALL, BackendConfig, BackendError, Outcome, apply_env, call_job, shipped_env,
                               test_kill, warn, worker_state)

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


def _task(init: Callable, job: Callable, setup: Any, item: Any, attempt: int, env: dict, kill: str) -> tuple[str, Any]:
    """The body of every Ray task: ``("done", value)``, ``("error", traceback)`` or ``("start_error", traceback)``."""
    import traceback

    apply_env(env)
    try:
        state = worker_state(init, setup)
    except Exception:  # noqa: BLE001 - the driver stops the run: every item would fail the same way
        return "start_error", traceback.format_exc()
    test_kill(kill, item, attempt)
    return call_job(job, state, item, attempt)


def _death_errors(ray: Any) -> tuple[type, ...]:
    """Ray's exceptions for a task whose worker, node or result was lost (not the job's own exception)."""
    ex = ray.exceptions
    names = ("WorkerCrashedError", "NodeDiedError", "ObjectLostError", "OwnerDiedError", "LocalRayletDiedError",
             "RaySystemError", "TaskUnschedulableError", "OutOfMemoryError")
    return tuple(getattr(ex, n) for n in names if isinstance(getattr(ex, n, None), type))


def run_ray(init: Callable, job: Callable, setup: Any, items: list, *, cfg: BackendConfig, workers: int,
            max_attempts: int, label: str, prog: str, kill: str = "") -> Iterator[Outcome]:
    """Run the items as Ray tasks, at most ``workers`` in flight (0: the cluster's CPUs); an iterator of
    outcomes. Connects to Ray now (an unreachable cluster fails here, before the first result)."""
    ray = ensure_ray(cfg)
    return _outcomes(ray, init, job, setup, items, workers=workers, max_attempts=max_attempts, label=label,
                     prog=prog, kill=kill)


def _outcomes(ray: Any, init: Callable, job: Callable, setup: Any, items: list, *, workers: int, max_attempts: int,
              label: str, prog: str, kill: str) -> Iterator[Outcome]:
    remote = ray.remote(num_cpus=1, max_retries=0)(_task)
    env = shipped_env()
    deaths = _death_errors(ray)
    limit = workers if workers > 0 else max(1, int(ray.cluster_resources().get("CPU", 1)))
    setup_ref = ray.put(setup)  # sent once, not with every task
    queue: deque = deque(items)
    attempts: dict[Any, int] = {}
    inflight: dict[Any, Any] = {}  # ObjectRef -> item

    def submit() -> None:
        while queue and len(inflight) < limit:
            item = queue.popleft()
            attempts[item] = attempts.get(item, 0) + 1
            inflight[remote.remote(init, job, setup_ref, item, attempts[item], env, kill)] = item

    try:
        submit()
        while inflight:
            ready, _ = ray.wait(list(inflight), num_returns=1)
            for ref in ready:
                item = inflight.pop(ref)
                try:
                    status, value = ray.get(ref)
                except deaths as exc:
                    why = type(exc).__name__
                    if attempts[item] >= max_attempts:
                        yield Outcome(item, error=f"its Ray worker died ({why}) on each of {attempts[item]} attempts",
                                      attempts=attempts[item])
                    else:
                        warn(prog, f"Ray worker died ({why}) on {label} {item}; {label} {item} goes back to the queue")
                        queue.appendleft(item)
                    continue
                except ray.exceptions.RayTaskError as exc:  # outside the job (e.g. unpickling its arguments)
                    yield Outcome(item, error=f"raised an exception:\n{exc}", attempts=attempts[item])
                    continue
                if status == "start_error":
                    raise BackendError(f"a Ray worker could not start:\n{value}")
                if status == "error":
                    yield Outcome(item, error=f"raised an exception:\n{value}", attempts=attempts[item])
                else:
                    yield Outcome(item, value=value, attempts=attempts[item])
            submit()
    finally:
        for ref in inflight:  # an error or Ctrl-C in the driver: the rest is not wanted
            try:
                ray.cancel(ref, force=True)
            except Exception:  # noqa: BLE001 - best effort; the instance goes at exit
                pass
