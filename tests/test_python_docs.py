"""docs/python.md: the code blocks, run in order as one script, do what the page says (issue 40)."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PAGE = ROOT / "docs" / "python.md"


def test_the_public_names_are_documented_and_none_is_a_subpackage():
    import pkgutil

    import pasta

    subpackages = {m.name for m in pkgutil.iter_modules(pasta.__path__)}
    names = [n for n in pasta.__all__ if n != "__version__"]
    assert not set(names) & subpackages, "a public name that a subpackage import would hide"
    text = PAGE.read_text()
    missing = [n for n in names if n[0].islower() and f"pasta.{n}(" not in text]
    assert not missing, f"public functions not on docs/python.md: {missing}"
    for name in names:
        assert getattr(pasta, name).__doc__, name


@pytest.mark.sim
def test_the_walk_through_runs(tmp_path):
    blocks = re.findall(r"```python\n(.*?)```", PAGE.read_text(), flags=re.S)
    assert len(blocks) >= 3
    script = tmp_path / "walk_through.py"
    script.write_text("\n".join(blocks))
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=900, cwd=tmp_path)
    assert done.returncode == 0, done.stderr[-3000:]
    out = done.stdout
    assert "crs" in out and "plan by exhaustive" in out and "normalised improvement" in out
    assert re.search(r"^complete \d+$", out, flags=re.M), out[-2000:]
