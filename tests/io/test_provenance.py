"""pasta.io.provenance: the record of versions, CPU and Taichi settings behind a result."""

from __future__ import annotations

import json
import platform

from pasta.io.provenance import CPU_FLAGS, PACKAGES, cpu_info, package_versions, provenance
from pasta.sim import SimConfig


def test_provenance_names_versions_cpu_and_taichi_settings():
    rec = provenance(sim_config=SimConfig())
    json.dumps(rec)  # JSON-able as it is (result rows, run-log metadata)
    assert rec["python"] == platform.python_version()
    assert list(rec["packages"]) == list(PACKAGES)
    import numpy
    import pasta

    assert rec["packages"]["numpy"] == numpy.__version__ and rec["packages"]["pasta"].startswith(pasta.__version__)
    assert rec["cpu"]["model"] and rec["cpu"]["count"] >= 1 and set(rec["cpu"]["flags"]) <= set(CPU_FLAGS)
    taichi = rec["taichi"]
    assert "fast_math" in taichi and "arch" in taichi
    if not taichi["initialised"]:  # before Taichi starts: the settings the SimConfig will start it with
        assert taichi["fast_math"] is False and taichi["cpu_max_num_threads"] == 2


def test_running_taichi_reports_its_compile_options():
    from pasta.sim.engine import ensure_taichi, taichi_settings

    ensure_taichi()  # the process's runtime (fast_math: the running value or the default, off)
    rec = provenance()["taichi"]
    assert rec["initialised"] and rec == {"initialised": True, **taichi_settings()}
    assert rec["arch"] == "cpu" and isinstance(rec["fast_math"], bool) and rec["default_fp"] == "f32"


def test_missing_package_and_cpu_fallback():
    assert package_versions(("surely-not-a-package-xyz",)) == {"surely-not-a-package-xyz": "not installed"}
    info = cpu_info()
    assert info["machine"] == platform.machine() and isinstance(info["flags"], list)
