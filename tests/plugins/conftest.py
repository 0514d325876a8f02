"""Fixtures for plugin tests: throwaway third-party distributions (a *.dist-info on sys.path, no pip)."""

from __future__ import annotations

import sys
import textwrap

import pytest


def write_dist_info(site, dist: str, version: str, entries: dict[str, str]) -> None:
    """A ``<dist>-<version>.dist-info`` under ``site`` whose ``pasta.plugins`` entry points map name -> module:
    what a pip install leaves for importlib.metadata to find."""
    info = site / f"{dist.replace('-', '_')}-{version}.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {dist}\nVersion: {version}\n")
    (info / "entry_points.txt").write_text("[pasta.plugins]\n" + "".join(f"{k} = {v}\n" for k, v in entries.items()))


@pytest.fixture
def make_dist(tmp_path, monkeypatch):
    """``make_dist(dist, module, source, entry="pinch")``: write distribution ``dist`` (version 0.3) whose
    entry point ``entry`` in ``pasta.plugins`` names module ``module`` with ``source``, and put it on sys.path.
    ``entry`` may also be a list of names (several entry points to the same module)."""
    monkeypatch.syspath_prepend(str(tmp_path))
    written = []

    def make(dist: str, module: str, source: str, entry: str | list[str] = "pinch"):
        entries = [entry] if isinstance(entry, str) else entry
        write_dist_info(tmp_path, dist, "0.3", dict.fromkeys(entries, module))
        (tmp_path / f"{module}.py").write_text(textwrap.dedent(source))
        written.append(module)
        return tmp_path

    yield make
    for module in written:
        sys.modules.pop(module, None)


@pytest.fixture
def install_example(tmp_path, monkeypatch, fresh_plugins):
    """``install_example(folder, dist, entry, package)``: the example package ``examples/<folder>`` as an installed
    distribution ``dist`` 0.1.0 would be (a *.dist-info whose entry point ``entry`` names ``<package>.plugin``,
    found by importlib.metadata like a pip install); returns the rescanned plugins. Its modules are unloaded after."""
    from pathlib import Path

    packages = []

    def install(folder: str, dist: str, entry: str, package: str):
        site = tmp_path / "site"
        write_dist_info(site, dist, "0.1.0", {entry: f"{package}.plugin"})
        monkeypatch.syspath_prepend(str(Path(__file__).resolve().parents[2] / "examples" / folder))
        monkeypatch.syspath_prepend(str(site))
        packages.append(package)
        return fresh_plugins()

    yield install
    for name in [m for m in sys.modules if any(m == p or m.startswith(p + ".") for p in packages)]:
        sys.modules.pop(name)
