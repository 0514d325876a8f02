"""Any ``pasta`` command with the frozen legacy kernel (benchmarks/legacy_engine.py) behind today's Simulator.

    PASTA_TASK_CACHE=/tmp/legacy .venv/bin/python benchmarks/oracle_legacy.py eval task=crs method=oracle num=5 out=/tmp/legacy-eval

compared with ``PASTA_TASK_CACHE=/tmp/new .venv/bin/pasta eval task=crs method=oracle num=5 out=/tmp/new-eval`` measures what the
plugin-driven kernel changes at task level (use separate task caches: both kernels share the task key).
Only the knife, pusher and roller (in that order) are supported, as in the legacy kernel.
"""
import importlib.util
import sys
from pathlib import Path

import numpy as np

spec = importlib.util.spec_from_file_location("pasta_legacy_engine", Path(__file__).resolve().parent / "legacy_engine.py")
L = importlib.util.module_from_spec(spec); spec.loader.exec_module(L)
import pasta.sim.simulator as S  # noqa: E402
from pasta.sim.engine import ensure_taichi  # noqa: E402



class _Params:
    def __init__(self, ad): self.ad = ad
    def from_numpy(self, arr): self.ad.p10 = np.asarray(arr, np.float32); self.ad.push()
class _Tool:
    def __init__(self, ad): self.ad = ad
    def from_numpy(self, arr): self.ad.leg.tool.from_numpy(np.ascontiguousarray(arr[:3, :11]))
class Adapter:
    def __init__(self, leg):
        self.leg, self.owner, self.p10, self.fric = leg, None, None, np.zeros(3, np.float32)
        self.params, self.tool = _Params(self), _Tool(self)
    def push(self):
        if self.p10 is not None:
            self.leg.params.from_numpy(np.concatenate([self.p10, self.fric]).astype(np.float32))
    def set_tools(self, a):
        assert int(a["n_tools"]) == 3 and list(a["kind"][:3, 0]) == [1, 0, 2], a["kind"]
        self.fric = a["friction"][:3].astype(np.float32); self.push()
    def __getattr__(self, k): return getattr(self.leg, k)

_E = {}
def _get_engine(cfg):
    ensure_taichi(cfg.arch, cfg.cpu_threads)
    key = (cfg.n_grid, cfg.max_particles)
    if key not in _E:
        _E[key] = Adapter(L.LegacyEngine(cfg.n_grid, cfg.max_particles, scatter="serial"))
    return _E[key]
S._get_engine = _get_engine
from pasta.cli import main  # noqa: E402

sys.exit(main(sys.argv[1:]))
