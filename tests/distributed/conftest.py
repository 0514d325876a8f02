"""Ray fixtures: one local Ray instance (2 CPUs, a small object store) per test module, shut down after it.

Ray is an optional extra (``pip install pasta-dough[ray]``). Without it the Ray tests are skipped, except
where ``PASTA_REQUIRE_RAY=1`` (set by ``.ci/run``, which installs ``.[dev,ray]``): there a missing Ray
fails them, so CI cannot pass by skipping.
"""

from __future__ import annotations

import pytest
from _distributed_jobs import require_ray


@pytest.fixture(scope="module")
def ray_local():
    """A local Ray instance as the tests use it (the backend then joins it instead of starting its own)."""
    ray = require_ray()
    import _distributed_jobs

    ray.cloudpickle.register_pickle_by_value(_distributed_jobs)  # the test jobs are not an installed module
    if ray.is_initialized():
        ray.shutdown()
    ray.init(num_cpus=2, object_store_memory=200_000_000, include_dashboard=False, configure_logging=False)
    yield ray
    ray.shutdown()
