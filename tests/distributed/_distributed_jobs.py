"""Small jobs for the backend tests (module-level functions: Ray and ``spawn`` send them by reference or value),
:func:`require_ray`, and :func:`hang_guard` (a run that hangs fails its test instead of holding the suite)."""

from __future__ import annotations

import contextlib
import os
import signal
import time

from pasta.distributed import map_jobs

SETUP = {"scale": 10}


def init(setup):
    if setup.get("fail_init"):
        raise RuntimeError("init failed on purpose")
    if setup.get("stop_init"):  # a start that hangs: only the start-up limit ends it
        time.sleep(0.5)  # Ray first reports that the task began
        os.kill(os.getpid(), signal.SIGSTOP)
    return {"scale": setup["scale"], "pid": os.getpid()}


def job(state, item, attempt):
    if item == 3:
        raise ValueError(f"item {item} raises on purpose")
    return {"item": item, "value": item * state["scale"], "attempt": attempt, "pid": state["pid"]}


def run(backend, workers, items=(0, 1, 2, 3, 4), setup=SETUP, deadline_s=0.0):
    """``{item: Outcome}`` of the toy job over ``items``."""
    return {o.item: o for o in map_jobs(init, job, setup, list(items), backend=backend, workers=workers,
                                        deadline_s=deadline_s, label="toy", prog="test")}


@contextlib.contextmanager
def hang_guard(seconds=120):
    """Fail after ``seconds`` (SIGALRM; both backends' waits return to Python at least every second): a
    guard against a hang, not a timing check. The TimeoutError may surface chained to a SystemError when
    it interrupts Ray's wait."""
    def expired(signum, frame):
        raise TimeoutError(f"the run did not return within {seconds} s")

    before = signal.signal(signal.SIGALRM, expired)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, before)


def check_values(out, good=(0, 1, 2, 4)):
    """Every item but 3 has its value; 3 raised, reported at once with its item."""
    assert sorted(out) == [0, 1, 2, 3, 4]
    for i in good:
        assert out[i].ok and out[i].value["value"] == 10 * i, out[i].error
    assert not out[3].ok and "item 3 raises on purpose" in out[3].error and out[3].attempts == 1


def require_ray():
    """The ``ray`` module; skips the test without Ray, except under ``PASTA_REQUIRE_RAY=1`` (CI), where a
    missing Ray fails it."""
    if os.environ.get("PASTA_REQUIRE_RAY") == "1":
        import ray  # an ImportError fails the test: CI must run these

        return ray
    import pytest

    return pytest.importorskip("ray", reason="Ray is an optional extra: pip install pasta-dough[ray]")
