"""Small jobs for the backend tests (module-level functions: Ray and ``spawn`` send them by reference or value),
and :func:`require_ray`."""

from __future__ import annotations

import os

from pasta.distributed import map_jobs

SETUP = {"scale": 10}


def init(setup):
    if setup.get("fail_init"):
        raise RuntimeError("init failed on purpose")
    return {"scale": setup["scale"], "pid": os.getpid()}


def job(state, item, attempt):
    if item == 3:
        raise ValueError(f"item {item} raises on purpose")
    return {"item": item, "value": item * state["scale"], "attempt": attempt, "pid": state["pid"]}


def run(backend, workers, items=(0, 1, 2, 3, 4), setup=SETUP):
    """``{item: Outcome}`` of the toy job over ``items``."""
    return {o.item: o for o in map_jobs(init, job, setup, list(items), backend=backend, workers=workers,
                                        label="toy", prog="test")}


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
