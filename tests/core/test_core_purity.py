"""pasta.core is the leaf of the project: it imports nothing else of pasta and no heavy library at import."""

import ast
import pathlib
import subprocess
import sys

import pasta.core

CORE = pathlib.Path(pasta.core.__file__).parent


def _imported_modules(path: pathlib.Path) -> set[str]:
    tree = ast.parse(path.read_text())
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module:
            names.add(node.module)
    return names


def test_core_imports_nothing_else_of_pasta():
    offenders = {
        f"{p.name}: {m}"
        for p in CORE.glob("*.py")
        for m in _imported_modules(p)
        if m.split(".")[0] == "pasta" and not m.startswith("pasta.core")
    }
    assert not offenders, f"pasta.core must only import pasta.core: {sorted(offenders)}"


def test_importing_core_and_listing_plugins_does_not_import_torch_or_taichi():
    code = (
        "import sys, pasta.core\n"
        "from pasta.plugins import get_plugins\n"
        "p = get_plugins(); assert len(p.skills) >= 3, p.skills.names()\n"
        "heavy = sorted(m for m in sys.modules if m.split('.')[0] in ('torch', 'taichi'))\n"
        "print(heavy)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]", out.stdout
