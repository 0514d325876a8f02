"""replay --verify logic against a stand-in simulator (fast; the real one is in test_verify_sim.py)."""

import argparse
import io
from dataclasses import asdict, dataclass

import numpy as np
import pytest

import pasta.sim
from pasta.io import RunLogger
from pasta.io import replay


@dataclass
class FakeConfig:
    gain: float = 1.0
    cpu_threads: int = 2

    @classmethod
    def from_dict(cls, d):  # as SimConfig.from_dict, which replay uses
        return cls(**d)


class FakeState:
    def __init__(self, x):
        self.x = np.asarray(x, dtype=np.float32)

    def to_bytes(self):
        buf = io.BytesIO()
        np.savez(buf, x=self.x)
        return buf.getvalue()

    @classmethod
    def load(cls, f):
        with np.load(f, allow_pickle=False) as z:
            return cls(z["x"])


class FakeSim:
    """x moves by gain * action of the posed tool; parked tools do nothing; teleports are logged."""

    def __init__(self, cfg, *, tools=()):
        self.cfg, self.x, self.tools, self.events = cfg, None, {}, []

    def set_state(self, s):
        self.x = s.x.copy()

    def set_tool_pose(self, name, position, yaw=0.0):
        self.tools[name] = True
        self.events.append(("pose", name, tuple(position), yaw))

    def park_tool(self, name):
        self.tools[name] = False

    def step(self, actions):
        for name, a in actions.items():
            if self.tools.get(name):
                self.x = (self.x + self.cfg.gain * np.asarray(a, np.float32)).astype(np.float32)

    def get_state(self):
        return FakeState(self.x)

    def observe(self):
        return self.x[::2]


@pytest.fixture
def fake_sim(monkeypatch):
    monkeypatch.setattr(pasta.sim, "Simulator", FakeSim, raising=False)
    monkeypatch.setattr(pasta.sim, "SimConfig", FakeConfig, raising=False)
    monkeypatch.setattr(pasta.sim, "SimState", FakeState, raising=False)


def _episode(path, gain=1.0, tamper=0.0, final_attachment=True, observed=False):
    cfg = FakeConfig(gain=gain)
    x0 = np.random.default_rng(0).random((20, 3)).astype(np.float32)
    sim = FakeSim(cfg)
    sim.set_state(FakeState(x0))
    with RunLogger(path) as log:
        log.attach("initial_state.npz", FakeState(x0).to_bytes())
        log.attach_json("sim_config.json", asdict(cfg))
        sim.set_tool_pose("knife", [0.5, 0.3, 0.5], yaw=0.1)
        log.set_tool_pose(0, 0, "knife", [0.5, 0.3, 0.5], yaw=0.1)
        for i in range(5):
            a = np.array([0.0, -0.01, 0.001 * i], np.float32)
            sim.step({"knife": a})
            log.action(i, i, "knife", a)
            log.point_cloud("/dough", i, sim.observe() if observed else sim.x)
        sim.park_tool("knife")
        log.park_tool(5, 5, "knife")
        sim.step({"knife": np.ones(3, np.float32)})  # parked: no effect
        log.action(5, 5, "knife", np.ones(3))
        final = sim.x + tamper
        if final_attachment:
            log.attach("final_state.npz", FakeState(final).to_bytes())


def _run(argv):
    parser = argparse.ArgumentParser()
    replay.add_arguments(parser)
    return replay.run(parser.parse_args(argv))


def test_verify_ok_and_fail(fake_sim, tmp_path, capsys):
    good = tmp_path / "good.mcap"
    _episode(good)
    assert _run([str(good), "--verify"]) == 0
    out = capsys.readouterr().out
    assert "max deviation 0.000e+00" in out and "OK" in out and "6 env steps" in out

    bad = tmp_path / "bad.mcap"
    _episode(bad, tamper=1e-3)
    assert _run([str(bad), "--verify"]) == replay.EXIT_VERIFY_FAILED
    assert "FAILED" in capsys.readouterr().out
    assert _run([str(bad), "tolerance=1e-2", "--verify"]) == 0


def test_verify_threads_set_the_simulators_cpu_threads(fake_sim, tmp_path, monkeypatch):
    seen = []

    def sim(cfg, **kwargs):
        seen.append(cfg.cpu_threads)
        return FakeSim(cfg, **kwargs)

    monkeypatch.setattr(pasta.sim, "Simulator", sim)
    p = tmp_path / "r.mcap"
    _episode(p)
    assert _run([str(p), "threads=3", "--verify"]) == 0
    assert _run([str(p), "--verify"]) == 0
    assert seen == [3, 2]  # threads=0: the logged run's own


def test_verify_against_last_dough_cloud(fake_sim, tmp_path, capsys):
    p = tmp_path / "r.mcap"
    _episode(p, final_attachment=False)
    assert _run([str(p), "--verify"]) == 0
    p2 = tmp_path / "obs.mcap"
    _episode(p2, final_attachment=False, observed=True)  # /dough is an observation subset
    assert _run([str(p2), "--verify"]) == 0
    assert "last /dough" in capsys.readouterr().out
