"""Where independent jobs run: in this process, in local worker processes, or on a Ray cluster.

``pasta demos``, ``pasta eval`` and ``pasta pipeline`` hand their independent units of work (one demo,
one episode) to :func:`map_jobs`, which yields an :class:`Outcome` per item as each one completes. The
driver (the calling process) consumes the outcomes and is the only process that writes result files.

A job is two importable module-level functions (Ray and ``spawn`` send them by reference):

- ``init(setup) -> state``: the expensive part (simulator, models), built once per worker process and
  reused for every item that process gets (:func:`worker_state` caches it by ``setup``);
- ``job(state, item, attempt) -> value``: one item. An exception is reported as that item's failure
  at once (it would repeat); a worker *death* (SIGKILL, OOM, a lost node) costs one attempt and the
  item is retried, up to ``max_attempts``, then reported as failed. The other items go on either way.

Backends (``backend=local|ray``, :class:`BackendConfig`):

- ``local`` (default): ``workers=0`` runs the items in this process; ``workers=N`` in N supervised
  ``spawn`` processes (:mod:`pasta.distributed.local`).
- ``ray``: one Ray task per item (:mod:`pasta.distributed.ray_backend`); ``ray.address=auto`` (or
  ``host:port``) joins a running cluster, no address starts a local Ray instance. Ray is an optional
  extra, imported only here: ``pip install pasta-dough[ray]``.

Test hook: ``PASTA_TEST_KILL=K`` (read by the driver, sent with every item) makes the worker that starts
item ``K`` SIGKILL itself on every attempt, ``K@1`` on the first attempt only (both backends).
"""

from __future__ import annotations

import os
import signal
import sys
import traceback
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from pasta.core.errors import ConfigError, PastaError, did_you_mean

__all__ = ["BACKENDS", "BackendConfig", "BackendError", "Outcome", "map_jobs", "split_backend_args",
           "worker_state", "TEST_KILL_ENV", "MAX_ATTEMPTS", "MAX_WORKERS"]

BACKENDS = ("local", "ray")
#: attempts per item before it is reported as failed (a worker death costs one attempt)
MAX_ATTEMPTS = 2
#: the most workers a command's ``workers=`` asks for (more is a typo, not a machine)
MAX_WORKERS = 1024
TEST_KILL_ENV = "PASTA_TEST_KILL"
#: environment variables of the driver that every worker gets (caches, test hooks): ``PASTA_*``
SHIPPED_ENV_PREFIX = "PASTA_"
RAY_INSTALL = "pip install pasta-dough[ray]"


class BackendError(PastaError, RuntimeError):
    """Workers could not start, or the backend could not be reached (the message says which)."""


@dataclass
class BackendConfig:
    """``backend=local|ray`` and the ``ray.*`` keys of ``pasta demos``, ``pasta eval``, ``pasta pipeline``.

    Attributes:
        name: ``local`` or ``ray``.
        address: ``ray.address``: empty starts a local Ray instance in this process; ``auto`` joins the
            cluster started on this machine with ``ray start``; ``HOST:PORT`` or ``ray://HOST:PORT`` another.
        num_cpus: ``ray.num_cpus``: CPUs of a local Ray instance (0: every core); ignored with an address.
        object_store_mb: ``ray.object_store_mb``: object store of a local Ray instance (demos travel
            through it, about 1 MB each); ignored with an address.
    """

    name: str = "local"
    address: str = ""
    num_cpus: int = 0
    object_store_mb: int = 256

    def check(self) -> "BackendConfig":
        """Fail now, before any work, when the backend cannot be used here (Ray not installed)."""
        if self.name == "ray":
            from pasta.distributed.ray_backend import import_ray

            import_ray()
        return self

    def describe(self) -> str:
        if self.name != "ray":
            return "local"
        return f"ray ({'address ' + self.address if self.address else 'local instance'})"


_RAY_KEYS = {"ray.address": "address", "ray.num_cpus": "num_cpus", "ray.object_store_mb": "object_store_mb"}


def split_backend_args(items: Sequence[str] | Mapping[str, Any]) -> tuple[BackendConfig, Any]:
    """Take ``backend=`` and ``ray.*=`` out of ``key=value`` items; return the backend and the rest
    (a list of ``key=value`` strings, or a dict when ``items`` is a mapping).

    Raises :class:`ConfigError` (one line, exit 2) for an unknown backend or ``ray.*`` key, bad numbers,
    or ``ray.*`` given without ``backend=ray``.
    """
    from pasta.config.overrides import split_overrides

    pairs = list(items.items()) if isinstance(items, Mapping) else list(split_overrides([str(i) for i in items]).items())
    rest: dict[str, Any] = {}
    cfg = BackendConfig()
    ray_given: list[str] = []
    for key, value in pairs:
        if key == "backend":
            name = str(value).strip()
            if name not in BACKENDS:
                raise ConfigError(f"backend={name}: must be one of {', '.join(BACKENDS)}{did_you_mean(name, BACKENDS)}")
            cfg.name = name
        elif key.startswith("ray."):
            if key not in _RAY_KEYS:
                raise ConfigError(f"unknown key '{key}'{did_you_mean(key, list(_RAY_KEYS))}; ray keys: {', '.join(_RAY_KEYS)}")
            attr = _RAY_KEYS[key]
            if attr == "address":
                cfg.address = str(value).strip()
            else:
                from pasta.config.validate import check_int

                setattr(cfg, attr, check_int(value, key, low=0 if attr == "num_cpus" else 80,
                                             high=MAX_WORKERS if attr == "num_cpus" else 1 << 30))
            ray_given.append(key)
        else:
            rest[key] = value
    if ray_given and cfg.name != "ray":
        raise ConfigError(f"{ray_given[0]} is a setting of the Ray backend; add backend=ray")
    return cfg, (rest if isinstance(items, Mapping) else [f"{k}={v}" for k, v in rest.items()])


@dataclass
class Outcome:
    """What became of one item: ``value`` when it completed, otherwise ``error`` (why, with a traceback
    for an exception). ``attempts``: how many times it was started."""

    item: Any
    value: Any = None
    error: str | None = None
    attempts: int = 1

    @property
    def ok(self) -> bool:
        return self.error is None


# ------------------------------------------------------------------------------------------ worker side

_STATE: dict[Any, Any] = {}


def worker_state(init: Callable[[Any], Any], setup: Any) -> Any:
    """``init(setup)``, built once per process and setup (the simulator and models a worker reuses)."""
    key = (getattr(init, "__module__", ""), getattr(init, "__qualname__", repr(init)), _freeze(setup))
    if key not in _STATE:
        _STATE.clear()  # one setup per worker at a time: a new one frees the last one's memory
        _STATE[key] = init(setup)
    return _STATE[key]


def _freeze(value: Any) -> Any:
    if isinstance(value, Mapping):
        return tuple(sorted((str(k), _freeze(v)) for k, v in value.items()))
    if isinstance(value, (list, tuple)):
        return tuple(_freeze(v) for v in value)
    return value


def shipped_env() -> dict[str, str]:
    """The driver's ``PASTA_*`` environment (cache folders, test hooks), applied in every worker."""
    return {k: v for k, v in os.environ.items() if k.startswith(SHIPPED_ENV_PREFIX)}


def apply_env(env: Mapping[str, str]) -> None:
    for key, value in env.items():
        os.environ[key] = value


def test_kill(spec: str, item: Any, attempt: int) -> None:
    """The :data:`TEST_KILL_ENV` hook: SIGKILL this process when it starts item ``spec``."""
    if not spec:
        return
    target, _, only = spec.partition("@")
    if str(target) == str(item) and (not only or int(only) == attempt):
        os.kill(os.getpid(), signal.SIGKILL)


def call_job(job: Callable[[Any, Any, int], Any], state: Any, item: Any, attempt: int) -> tuple[str, Any]:
    """``("done", value)`` or ``("error", traceback)``: a job's exception never takes its worker down."""
    try:
        return "done", job(state, item, attempt)
    except Exception:  # noqa: BLE001 - reported with the item
        return "error", traceback.format_exc()


# ------------------------------------------------------------------------------------------ driver side


def map_jobs(init: Callable[[Any], Any], job: Callable[[Any, Any, int], Any], setup: Any, items: Sequence[Any], *,
             backend: BackendConfig | None = None, workers: int = 0, max_attempts: int = MAX_ATTEMPTS,
             label: str = "item", prog: str = "pasta", state: Any = None) -> Iterator[Outcome]:
    """Run ``job(init(setup), item, attempt)`` for every item; yield an :class:`Outcome` per item as it
    completes (in completion order, not item order).

    ``workers``: local worker processes (0: this process), or with Ray the most items in flight at once
    (0: as many as the cluster has CPUs). ``label``/``prog``: how warnings name an item and the command.
    ``state``: ``init(setup)`` already built by the caller, used when the items run in this process.

    Raises:
        BackendError: workers cannot start (``init`` failed, or they keep dying outside any item), or
            the Ray cluster cannot be reached.
        ConfigError: ``backend=ray`` without Ray installed (``pip install pasta-dough[ray]``).
    """
    backend = backend or BackendConfig()
    items = list(items)
    if not items:
        return iter(())
    kill = os.environ.get(TEST_KILL_ENV, "")
    if backend.name == "ray":
        from pasta.distributed.ray_backend import import_ray, run_ray

        import_ray()  # a missing Ray fails here, not at the first result

        return run_ray(init, job, setup, items, cfg=backend, workers=workers, max_attempts=max_attempts,
                       label=label, prog=prog, kill=kill)
    if workers > 0 and len(items) > 1:
        from pasta.distributed.local import run_local

        return run_local(init, job, setup, items, workers=min(workers, len(items)), max_attempts=max_attempts,
                         label=label, prog=prog, kill=kill)
    return _in_process(init, job, setup, items, state)


def _in_process(init: Callable, job: Callable, setup: Any, items: list, state: Any) -> Iterator[Outcome]:
    state = init(setup) if state is None else state
    for item in items:
        status, value = call_job(job, state, item, 1)
        yield Outcome(item, value=value) if status == "done" else Outcome(item, error=f"raised an exception:\n{value}")


def warn(prog: str, text: str) -> None:
    print(f"{prog}: warning: {text}", file=sys.stderr, flush=True)

