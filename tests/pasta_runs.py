"""A short `pasta run` for the log tests: its command line, and the same run as a separate process whose log is
read while it is written (tests/io: crash safety, one writer per log, JSON schemas)."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

from pasta.io import RunReader

#: shipped weights, heuristic controllers, a short optimisation: ~10 s of CPU
RUN = ["run", "task=crs", "seed=1000", "planner.iterations=10", "execute.idle_steps=2", "execute.retries=0"]


def start_run(log: Path, seed: int = 1000) -> subprocess.Popen:
    """``pasta run`` (:data:`RUN` with ``seed``) logging to ``log``, in its own process (stderr captured)."""
    args = [a for a in RUN if not a.startswith("seed=")] + [f"seed={seed}", f"log={log}"]
    return subprocess.Popen([sys.executable, "-m", "pasta", *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)


def wait_for_steps(partial: Path, proc: subprocess.Popen, steps: int, timeout: float = 240.0) -> int:
    """Poll the run's ``.partial`` log until it holds ``steps`` finished steps (or the run ends, or ``timeout``);
    the steps seen."""
    deadline, seen = time.monotonic() + timeout, 0
    while seen < steps and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.3)
        if partial.exists():  # read while it is written: recover keeps what is complete so far
            try:
                seen = RunReader(partial, recover=True).count("/step")
            except Exception:  # noqa: BLE001 - the header may not be complete yet
                seen = 0
    return seen
