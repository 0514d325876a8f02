"""benchmarks/repeated_steps.py: which plan steps re-apply a 1 -> 1 skill to the piece the step before produced."""

from __future__ import annotations

import importlib.util
from pathlib import Path
from types import SimpleNamespace

from pasta.core import SkillSpec

_PATH = Path(__file__).resolve().parents[2] / "benchmarks" / "repeated_steps.py"
_spec = importlib.util.spec_from_file_location("repeated_steps", _PATH)
repeated_steps = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(repeated_steps)

SKILLS = {name: SimpleNamespace(spec=SkillSpec(name=name, n_in=1, n_out=m, tool="t")) for name, m in
          (("cut", 2), ("push", 1), ("roll", 1))}


def _plan(*steps):
    return SimpleNamespace(steps=[SimpleNamespace(skill=s, inputs=tuple(i)) for s, i in steps])


def test_a_roll_of_the_piece_the_roll_before_produced_is_a_repeat():
    # crs_twice as planned on seed 2001: the last roll takes row 0, the first roll's output
    plan = _plan(("cut", [0]), ("cut", [0]), ("push", [0]), ("push", [1]), ("roll", [1]), ("roll", [0]))
    assert repeated_steps.repeated_steps(plan, SKILLS) == [5]
    # rolling the other piece is not a repeat, nor is a cut of a cut's output (1 -> 2) or a push after a roll
    plan = _plan(("cut", [0]), ("cut", [0]), ("push", [0]), ("push", [1]), ("roll", [1]), ("roll", [1]))
    assert repeated_steps.repeated_steps(plan, SKILLS) == []
    assert repeated_steps.repeated_steps(_plan(("roll", [0]), ("push", [0])), SKILLS) == []


def test_seed_ranges():
    assert repeated_steps.parse_seeds("2000-2002,2010") == [2000, 2001, 2002, 2010]
    assert repeated_steps.parse_seeds("7") == [7]
