"""The ``pasta`` console script (``pasta_dough:main``) names a foreign ``pasta`` package in one line (issue 40).

google-pasta, a TensorFlow dependency, installs an import package of the same name: installed beside
pasta-dough it replaces ``pasta/__init__.py``, uninstalled afterwards it deletes it. The tests build both
situations on ``PYTHONPATH`` (found before the installed pasta) and run the launcher in a subprocess.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

LAUNCH = "import sys; from pasta_dough import main; sys.exit(main(['plugins']))"


def _launch(path: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(path)}
    elsewhere = path / "cwd"  # not the checkout: its pasta/ would be found first
    elsewhere.mkdir()
    return subprocess.run([sys.executable, "-c", LAUNCH], capture_output=True, text=True, env=env, timeout=120,
                          cwd=elsewhere)


def test_the_launcher_runs_pasta_when_pasta_is_ours():
    from pasta_dough import foreign_pasta

    assert foreign_pasta() is None


def test_a_pasta_package_of_another_distribution_is_named_with_the_fix(tmp_path):
    (tmp_path / "pasta").mkdir()
    (tmp_path / "pasta" / "__init__.py").write_text('"""Pasta enables AST-based transformations."""\n')
    info = tmp_path / "google_pasta-0.2.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: google-pasta\nVersion: 0.2.0\n")
    (info / "RECORD").write_text("pasta/__init__.py,,\ngoogle_pasta-0.2.0.dist-info/METADATA,,\n")
    done = _launch(tmp_path)
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 2 and len(lines) == 1, done.stderr
    assert lines[0].startswith("pasta: error: the import package 'pasta' at ") and "google-pasta 0.2.0" in lines[0]
    assert "pip uninstall -y google-pasta" in lines[0] and "Traceback" not in done.stderr


def test_our_package_without_its_init_says_what_deleted_it(tmp_path):
    (tmp_path / "pasta").mkdir()
    (tmp_path / "pasta" / "cli.py").write_text("")  # what an uninstall of google-pasta leaves of ours
    done = _launch(tmp_path)
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 2 and len(lines) == 1, done.stderr
    assert "__init__.py is missing (uninstalling google-pasta" in lines[0] and "pip install --force-reinstall" in lines[0]
