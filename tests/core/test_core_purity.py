"""Importing pasta.core and listing plugins import no heavy library (torch, taichi).

That pasta.core imports nothing else of pasta is part of the layer test (tests/test_layers.py: core is
layer 0, so any import of another unit from it points up).
"""

import subprocess
import sys

HEAVY = "sorted(m for m in sys.modules if m.split('.')[0] in ('torch', 'taichi'))"


def _run(code: str) -> str:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()


def test_importing_core_and_listing_plugins_does_not_import_torch_or_taichi():
    code = (
        "import sys, pasta.core\n"
        "from pasta.plugins import get_plugins\n"
        "p = get_plugins(); assert len(p.skills) >= 3, p.skills.names()\n"
        f"print({HEAVY})\n"
    )
    assert _run(code) == "[]"


def test_pasta_plugins_command_does_not_import_torch_or_taichi():
    """The CLI imports every command module to build its parser; `pasta plugins` must stay light."""
    code = (
        "import contextlib, io, sys\n"
        "from pasta.cli import main\n"
        "with contextlib.redirect_stdout(io.StringIO()) as out:\n"
        "    rc = main(['plugins'])\n"
        "assert rc == 0 and 'pc_vae' in out.getvalue(), (rc, out.getvalue())\n"
        f"print({HEAVY})\n"
    )
    assert _run(code) == "[]"
