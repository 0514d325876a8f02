"""What produced a result: package versions, platform, CPU, Taichi arch and compile options, thread counts.

:func:`provenance` is recorded in every ``pasta eval`` result row and summary and in every ``pasta run``
log (metadata record :data:`PROVENANCE_RECORD`), because the simulator's floating-point results depend on
the CPU's instruction set, the libraries' versions and Taichi's ``fast_math`` (docs/simulator.md,
"Reproducibility"). Nothing here imports torch or taichi: their state is read only if already loaded.
"""

from __future__ import annotations

import os
import platform
import sys
from importlib import metadata
from typing import Any

#: name of the run-log metadata record holding :func:`provenance`
PROVENANCE_RECORD = "provenance"

#: distributions whose versions change numbers (``pasta``: this package's ``__version__``)
PACKAGES = ("pasta", "numpy", "torch", "taichi", "scipy", "scikit-learn", "pot", "omegaconf")

#: CPU features that change which machine code LLVM (Taichi) and numpy's SIMD loops run
CPU_FLAGS = ("sse4_2", "avx", "avx2", "fma", "avx512f", "avx512dq", "avx512vl", "asimd", "sve")


def provenance(sim_config: Any = None) -> dict[str, Any]:
    """A JSON-able record of the software and machine behind a result.

    Args:
        sim_config: a :class:`pasta.sim.SimConfig`; when Taichi is not running yet, its ``arch``,
            ``fast_math`` and ``cpu_threads`` are recorded as the settings Taichi will start with.

    Returns:
        ``{"python", "packages": {name: version}, "platform", "libc", "cpu": {"model", "count", "flags"},
        "taichi": {"arch", "fast_math", ...}, "torch_threads"}``.
    """
    return {
        "python": platform.python_version(),
        "packages": package_versions(),
        "platform": platform.platform(),
        "libc": " ".join(platform.libc_ver()).strip(),  # its libm computes the kernels' exp/log
        "cpu": cpu_info(),
        "taichi": taichi_info(sim_config),
        "torch_threads": _torch_threads(),
    }


def package_versions(names: tuple[str, ...] = PACKAGES) -> dict[str, str]:
    """``{distribution: version}`` (``"not installed"`` for a missing one); reads metadata, imports nothing."""
    out = {}
    for name in names:
        if name == "pasta":  # the code that ran (the distribution's name differs, and a checkout may be newer)
            from pasta._version import __version__

            commit = _git_commit()
            out[name] = __version__ + (f"+g{commit}" if commit else "")
            continue
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "not installed"
    return out


def cpu_info() -> dict[str, Any]:
    """The CPU model (``/proc/cpuinfo`` or :func:`platform.processor`), the logical core count and the
    instruction-set flags of :data:`CPU_FLAGS` that it has."""
    model = ""
    flags: set[str] = set()
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as f:
            for line in f:
                key, _, value = line.partition(":")
                key = key.strip()
                if key in ("model name", "Model", "Hardware", "cpu model") and not model:
                    model = value.strip()
                elif key in ("flags", "Features") and not flags:
                    flags = set(value.split())
    except OSError:  # not Linux: fall back to what platform knows
        pass
    return {"model": model or platform.processor() or platform.machine() or "unknown",
            "machine": platform.machine(), "count": os.cpu_count() or 0,
            "flags": [f for f in CPU_FLAGS if f in flags]}


def taichi_info(sim_config: Any = None) -> dict[str, Any]:
    """The running Taichi runtime's arch and compile options; before Taichi starts, the settings it will
    start with (``"initialised": false``)."""
    engine = sys.modules.get("pasta.sim.engine")
    settings = engine.taichi_settings() if engine is not None else {}
    if settings:
        return {"initialised": True, **settings}
    out: dict[str, Any] = {"initialised": False}
    if sim_config is not None:
        out.update(arch=str(sim_config.arch), fast_math=bool(sim_config.fast_math),
                   cpu_max_num_threads=int(sim_config.cpu_threads))
    return out


def _git_commit() -> str:
    """The short commit of a git checkout pasta runs from ("" when installed from a wheel or git is missing)."""
    import subprocess
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    if not (root / ".git").exists():
        return ""
    try:
        out = subprocess.run(["git", "-C", str(root), "rev-parse", "--short=12", "HEAD"], capture_output=True,
                             text=True, timeout=5, check=False)
    except (OSError, subprocess.SubprocessError):
        return ""
    return out.stdout.strip() if out.returncode == 0 else ""


def _torch_threads() -> int | None:
    torch = sys.modules.get("torch")
    return int(torch.get_num_threads()) if torch is not None else None


__all__ = ["CPU_FLAGS", "PACKAGES", "PROVENANCE_RECORD", "cpu_info", "package_versions", "provenance", "taichi_info"]
