"""Fixtures for plugin tests: throwaway third-party distributions (a *.dist-info on sys.path, no pip)."""

from __future__ import annotations

import sys
import textwrap

import pytest


@pytest.fixture
def make_dist(tmp_path, monkeypatch):
    """``make_dist(dist, module, source, entry="pinch")``: write distribution ``dist`` (version 0.3) whose
    entry point ``entry`` in ``pasta.plugins`` names module ``module`` with ``source``, and put it on sys.path.
    ``entry`` may also be a list of names (several entry points to the same module)."""
    monkeypatch.syspath_prepend(str(tmp_path))
    written = []

    def make(dist: str, module: str, source: str, entry: str | list[str] = "pinch"):
        info = tmp_path / f"{dist.replace('-', '_')}-0.3.dist-info"
        info.mkdir()
        (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {dist}\nVersion: 0.3\n")
        entries = [entry] if isinstance(entry, str) else entry
        (info / "entry_points.txt").write_text("[pasta.plugins]\n" + "".join(f"{e} = {module}\n" for e in entries))
        (tmp_path / f"{module}.py").write_text(textwrap.dedent(source))
        written.append(module)
        return tmp_path

    yield make
    for module in written:
        sys.modules.pop(module, None)
