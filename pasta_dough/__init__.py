"""The ``pasta`` console script of the pasta-dough distribution.

The import name ``pasta`` is also used by another distribution, google-pasta (a TensorFlow dependency):
installing it beside pasta-dough overwrites ``pasta/__init__.py``, and uninstalling it afterwards deletes that
file, so ``pasta.cli`` either imports the wrong package or none. This launcher has a name of its own, checks
which ``pasta`` Python would import (without importing it), and says in one line what replaced it and how to
fix the environment, instead of a traceback from inside the other package.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path

#: a line of pasta-dough's ``pasta/__init__.py`` docstring, which another package's ``pasta`` does not have
MARKER = "PASTA, CoRL 2022"
FIX = ("fix: give pasta-dough its own virtual environment, or run `pip uninstall -y google-pasta` and then "
       "`pip install --force-reinstall --no-deps pasta-dough`")


def main(argv: Sequence[str] | None = None) -> int:
    problem = foreign_pasta()
    if problem is not None:
        print(f"pasta: error: {problem}; {FIX}", file=sys.stderr)
        return 2
    from pasta.cli import main as cli

    return cli(argv)


def foreign_pasta() -> str | None:
    """Why the ``pasta`` package Python would import is not pasta-dough's, or None when it is."""
    from importlib.util import find_spec

    try:
        spec = find_spec("pasta")
    except (ImportError, ValueError) as exc:
        return f"the import package 'pasta' cannot be found ({exc})"
    if spec is None or not spec.submodule_search_locations:
        return "the import package 'pasta' is missing"
    folder = Path(next(iter(spec.submodule_search_locations)))
    init = folder / "__init__.py"
    if not init.is_file():
        if (folder / "cli.py").is_file():  # our files without our __init__: the other package's uninstall took it
            return (f"pasta-dough's {init} is missing (uninstalling google-pasta, which installs a package of the "
                    "same import name, deletes it)")
        return f"the import package 'pasta' at {folder} is not pasta-dough's"
    if (folder / "cli.py").is_file() and MARKER in init.read_text(errors="replace"):
        return None
    return f"the import package 'pasta' at {folder} is not pasta-dough's: it comes from {_owner(init)}"


def _owner(init: Path) -> str:
    """The distribution that installed ``init`` (``pasta/__init__.py`` in its RECORD), as ``NAME VERSION``."""
    from importlib import metadata

    for dist in metadata.distributions():
        if dist.metadata["Name"] in (None, "pasta-dough"):
            continue
        for f in dist.files or ():
            if str(f).replace("\\", "/") == "pasta/__init__.py":
                try:
                    if Path(str(dist.locate_file(f))).resolve() == init.resolve():
                        return f"{dist.metadata['Name']} {dist.version}"
                except OSError:
                    continue
    return "another distribution"
