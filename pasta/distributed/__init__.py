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

Deadlines (``deadline_s``, the key ``deadline_s=`` of the commands): a worker that stops answering (hung,
stopped, swapping) would otherwise hold the run forever. An item still running ``deadline_s`` seconds
after its worker started it (the clock starts when the worker has its state, so ``init`` is not counted)
is abandoned: its worker is killed (local) or its task cancelled (Ray), and that costs one attempt, as a
death does; after ``max_attempts`` the item is reported as failed (``it exceeded its deadline of N s on
each of 2 attempts``). A worker's start (``init``) has its own limit, ``max(STARTUP_S, deadline_s)``.
The commands derive the default from the size of the work (:func:`sized_deadline`: the first item of a
worker also compiles the simulator's kernels); ``deadline_s=0`` here means no deadline. Items run in
this process (``workers=0``) cannot be abandoned: they have none.

Backends (``backend=local|ray``, :class:`BackendConfig`):

- ``local`` (default): ``workers=0`` runs the items in this process; ``workers=N`` in N supervised
  ``spawn`` processes (:mod:`pasta.distributed.local`).
- ``ray``: one Ray task per item (:mod:`pasta.distributed.ray_backend`); ``ray.address=auto`` (or
  ``host:port``) joins a running cluster, no address starts a local Ray instance. Ray is an optional
  extra, imported only here: ``pip install pasta-dough[ray]``.

Test hooks (read by the driver, sent with every item; both backends): ``PASTA_TEST_KILL=K`` makes the
worker that starts item ``K`` SIGKILL itself on every attempt, ``K@1`` on the first attempt only;
``PASTA_TEST_STOP=K`` (``K@1``) makes it SIGSTOP itself instead (a hung worker: only its deadline ends it).
"""

from __future__ import annotations

import math
import os
import signal
import sys
import time
import traceback
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from pasta.core.errors import ConfigError, PastaError, did_you_mean

__all__ = ["BACKENDS", "BACKEND_KEYS", "BackendConfig", "BackendError", "Outcome", "map_jobs", "sized_deadline",
           "split_backend_args", "worker_state", "TEST_KILL_ENV", "TEST_STOP_ENV", "MAX_ATTEMPTS", "MAX_WORKERS",
           "STARTUP_S"]

BACKENDS = ("local", "ray")
#: the keys :func:`split_backend_args` takes out of a command line (the same on every command that has them)
BACKEND_KEYS = ("backend", "deadline_s", "ray.address", "ray.num_cpus", "ray.object_store_mb")
#: attempts per item before it is reported as failed (a worker death or a passed deadline costs one attempt)
MAX_ATTEMPTS = 2
#: what a worker's start may take (imports, simulator, models) and, in a derived deadline, its first item's
#: kernel compile: 66 s on an idle 2-core machine with a cold Taichi cache, several minutes on a loaded one
STARTUP_S = 600.0
#: a derived deadline's bound on one simulator step at :data:`STEP_PARTICLES` particles: an env step takes
#: ~45 ms on an idle 2-core machine and ~0.1-0.3 s on a loaded one, so this is 3-20 times that
STEP_S = 1.0
STEP_PARTICLES = 5000
#: the most workers a command's ``workers=`` asks for (more is a typo, not a machine)
MAX_WORKERS = 1024
TEST_KILL_ENV = "PASTA_TEST_KILL"
TEST_STOP_ENV = "PASTA_TEST_STOP"
#: the signal each test hook sends
_TEST_SIGNALS = {TEST_KILL_ENV: signal.SIGKILL, TEST_STOP_ENV: signal.SIGSTOP}
#: a stopped worker first lets its backend report that the item started (Ray sends that in the background)
_STOP_PAUSE_S = 0.5
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
        deadline_s: ``deadline_s``: seconds an item may run in a worker before the worker is given up
            (killed or cancelled) and the item retried or reported; 0: the command's default, derived from
            the size of its work (:func:`sized_deadline`). Not used for items run in this process.
    """

    name: str = "local"
    address: str = ""
    num_cpus: int = 0
    object_store_mb: int = 256
    deadline_s: float = 0.0

    def check(self) -> BackendConfig:
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
    """Take ``backend=``, ``deadline_s=`` and ``ray.*=`` (:data:`BACKEND_KEYS`) out of ``key=value`` items;
    return the backend and the rest (a list of ``key=value`` strings, or a dict when ``items`` is a mapping).

    Raises :class:`ConfigError` (one line, exit 2) for an unknown backend or ``ray.*`` key, bad numbers
    (a negative or non-numeric ``deadline_s``), or ``ray.*`` given without ``backend=ray``.
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
        elif key == "deadline_s":
            cfg.deadline_s = check_deadline(value)
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


def check_deadline(value: Any) -> float:
    """``deadline_s=`` as seconds >= 0, or a one-line :class:`ConfigError` that names the key."""
    from pasta.config.validate import check_number

    try:
        return check_number(value, "deadline_s", low=0.0)
    except ConfigError as exc:
        raise ConfigError(f"{exc} (seconds an item may run in a worker; 0: derived from the size of the "
                          "work)") from None


def sized_deadline(steps: int, n_particles: int = STEP_PARTICLES, extra_s: float = 0.0) -> float:
    """A deadline for an item of ``steps`` simulator steps at ``n_particles`` particles, plus ``extra_s`` of
    other work (planning): :data:`STARTUP_S` (the first item of a worker compiles the kernels) + ``extra_s``
    + :data:`STEP_S` per step, scaled up with the particles. Generous on purpose: it is there to catch a
    worker that stopped answering, not a slow one."""
    scale = max(1.0, n_particles / STEP_PARTICLES)
    return round(STARTUP_S + extra_s + STEP_S * max(0, steps) * scale)


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


def read_test_hooks() -> dict[str, str]:
    """The test hooks set in the driver's environment (:data:`TEST_KILL_ENV`, :data:`TEST_STOP_ENV`), sent
    with every item."""
    return {name: os.environ[name] for name in _TEST_SIGNALS if os.environ.get(name)}


def run_test_hooks(hooks: Mapping[str, str], item: Any, attempt: int) -> None:
    """The test hooks: SIGKILL or SIGSTOP this process when it starts the item a hook names (``K``, or
    ``K@A``: on attempt ``A`` only)."""
    for name, spec in hooks.items():
        target, _, only = spec.partition("@")
        if str(target) == str(item) and (not only or int(only) == attempt):
            if _TEST_SIGNALS[name] == signal.SIGSTOP:
                time.sleep(_STOP_PAUSE_S)
            os.kill(os.getpid(), _TEST_SIGNALS[name])


def job_error(trace: str) -> str:
    """An item's error from its job's traceback: ``raised Type: message`` (the traceback's last line, so a
    report's first line says what went wrong), then the traceback."""
    last = next((line for line in reversed(str(trace).strip().splitlines()) if line.strip()), "an exception")
    name, sep, message = last.partition(":")
    name = name.rpartition(".")[2] if " " not in name else name  # pasta.core.errors.InputError -> InputError
    return f"raised {name}{sep}{message}\n{trace}"


def call_job(job: Callable[[Any, Any, int], Any], state: Any, item: Any, attempt: int) -> tuple[str, Any]:
    """``("done", value)`` or ``("error", traceback)``: a job's exception never takes its worker down."""
    try:
        return "done", job(state, item, attempt)
    except Exception:  # noqa: BLE001 - reported with the item
        return "error", traceback.format_exc()


# ------------------------------------------------------------------------------------------ driver side


def map_jobs(init: Callable[[Any], Any], job: Callable[[Any, Any, int], Any], setup: Any, items: Sequence[Any], *,
             backend: BackendConfig | None = None, workers: int = 0, max_attempts: int = MAX_ATTEMPTS,
             deadline_s: float = 0.0, label: str = "item", prog: str = "pasta",
             state: Any = None) -> Iterator[Outcome]:
    """Run ``job(init(setup), item, attempt)`` for every item; yield an :class:`Outcome` per item as it
    completes (in completion order, not item order).

    ``workers``: local worker processes (0: this process), or with Ray the most items in flight at once
    (0: as many as the cluster has CPUs). ``deadline_s``: seconds an item may run in a worker before it is
    abandoned and retried (see the module docstring; 0: no deadline). Items run in this process
    (``workers=0``, or a single item under ``backend=local``) cannot be abandoned: ``deadline_s`` does not
    apply to them. ``label``/``prog``: how warnings name an item and the command. ``state``:
    ``init(setup)`` already built by the caller, used when the items run in this process.

    Raises:
        BackendError: workers cannot start (``init`` failed, or they keep dying outside any item), or
            the Ray cluster cannot be reached.
        ConfigError: ``backend=ray`` without Ray installed (``pip install pasta-dough[ray]``).
    """
    backend = backend or BackendConfig()
    items = list(items)
    if not items:
        return iter(())
    hooks = read_test_hooks()
    deadline_s = check_deadline(deadline_s)
    if backend.name == "ray":
        from pasta.distributed.ray_backend import import_ray, run_ray

        import_ray()  # a missing Ray fails here, not at the first result

        return run_ray(init, job, setup, items, cfg=backend, workers=workers, max_attempts=max_attempts,
                       deadline_s=deadline_s, label=label, prog=prog, hooks=hooks)
    if workers > 0 and len(items) > 1:
        from pasta.distributed.local import run_local

        return run_local(init, job, setup, items, workers=min(workers, len(items)), max_attempts=max_attempts,
                         deadline_s=deadline_s, label=label, prog=prog, hooks=hooks)
    return _in_process(init, job, setup, items, state)


def _in_process(init: Callable, job: Callable, setup: Any, items: list, state: Any) -> Iterator[Outcome]:
    state = init(setup) if state is None else state
    for item in items:
        status, value = call_job(job, state, item, 1)
        yield Outcome(item, value=value) if status == "done" else Outcome(item, error=job_error(value))


def warn(prog: str, text: str) -> None:
    print(f"{prog}: warning: {text}", file=sys.stderr, flush=True)


# ------------------------------------------------------------------------------- driver side: deadlines


def due_time(seconds: float) -> float:
    """The :func:`time.monotonic` time ``seconds`` from now; ``inf`` for 0 (no deadline)."""
    return time.monotonic() + seconds if seconds > 0 else math.inf


def wait_timeout(dues: Iterable[float], cap: float | None = None) -> float | None:
    """How long the driver may block waiting for its workers: until the nearest due time (never longer:
    an overdue item is noticed on time), at most ``cap``; ``None``: no limit (nothing is due, no cap)."""
    nearest = min(dues, default=math.inf)
    if math.isinf(nearest):
        return cap
    left = max(0.0, nearest - time.monotonic())
    return left if cap is None else min(cap, left)


def seconds(value: float) -> str:
    """``3``, ``2.5``, ``1260``: a deadline in a message."""
    return f"{value:.0f}" if value >= 10 or float(value).is_integer() else f"{value:g}"


def overdue_reason(deadline_s: float) -> str:
    return f"it exceeded its deadline of {seconds(deadline_s)} s"


def attempts_error(reasons: Sequence[str]) -> str:
    """The error of an item that used up its attempts: ``<reason> on each of N attempts`` when every attempt
    ended the same way, else each attempt's reason; a passed deadline names the key that sets it."""
    if len(set(reasons)) == 1:
        text = f"{reasons[0]} on each of {len(reasons)} attempts"
    else:
        text = ", ".join(f"{why} on attempt {n}" for n, why in enumerate(reasons, 1))
    if any(why.startswith("it exceeded its deadline") for why in reasons):
        text += " (deadline_s= sets the deadline)"
    return text

