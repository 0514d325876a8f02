"""Names kept for ``pasta demos``' worker processes, which now run on :mod:`pasta.distributed`.

The supervised local worker processes (a dead worker's demo re-queued, two deaths -> reported with its
seed, a worker past its ``deadline_s`` killed the same way, workers die with the parent) are
:mod:`pasta.distributed.local`; the Ray backend is :mod:`pasta.distributed.ray_backend`. The test hooks are
:data:`pasta.distributed.TEST_KILL_ENV` (``PASTA_TEST_KILL=K``: the worker that starts demo ``K`` SIGKILLs
itself, ``K@1`` on the first attempt only) and :data:`pasta.distributed.TEST_STOP_ENV` (``PASTA_TEST_STOP``:
SIGSTOP instead).
"""

from __future__ import annotations

from pasta.distributed import MAX_ATTEMPTS, TEST_KILL_ENV, BackendError

__all__ = ["MAX_ATTEMPTS", "TEST_KILL_ENV", "DemoWorkerError"]


class DemoWorkerError(BackendError):
    """Demo workers could not start, or some demos could not be made (the message names them and their seeds)."""
