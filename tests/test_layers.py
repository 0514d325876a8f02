"""The layer order of pasta's packages, and a test that every import points down it.

Every module of ``pasta/`` and of the plugin packages under ``plugins/`` is parsed with :mod:`ast`; an
import is any ``import``/``from ... import`` statement, wherever it stands (module level, inside a function
or under ``if TYPE_CHECKING``), and any string constant that names a module of the tree exactly (the
``importlib.import_module("pasta...")`` targets, the ``"module:attribute"`` factories a plugin registers,
lazy export tables), plus the constant prefix of an f-string passed to ``importlib.import_module``.

Rules (:data:`LAYERS` is the one declaration of the order; documents quote it from here):

1. An import may only point down :data:`LAYERS`; imports inside one unit (a package of the table, or one
   plugin package) are free.
2. Peers, different units of one layer, do not import each other, except :data:`PEER_EXCEPTIONS`.
3. ``pasta.*`` never imports a plugin package: it finds plugins through the registry.
4. A plugin package never imports another plugin package.
5. :data:`FORBIDDEN` pairs, though they point down.

Violations that other work in progress removes are listed in :data:`PENDING`; the test prints them, and
fails when one no longer occurs, so the list shrinks to empty as that work lands.
"""

from __future__ import annotations

import ast
import warnings
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

#: The layer order, bottom (0) to top: layer -> its units. A unit is a package (or module) of pasta with
#: every module under it; each plugin package under plugins/ (:data:`PLUGIN_PACKAGES`) is a unit of its own.
LAYERS: dict[int, tuple[str, ...]] = {
    0: ("pasta.core",),  # the vocabulary and the contracts
    1: ("pasta.plugins",),  # hook specifications and the registry, nothing else
    2: ("pasta.sim", "pasta.weights"),
    3: ("pasta.config",),  # the one run config: every setting of a run, the simulator's section included
    4: ("pasta.io", "pasta.distributed", "pasta.perception"),
    5: ("pasta.planning", "pasta.tasks"),  # tasks: the machinery (Task base, Generation, run_skill, oracle)
    6: ("pasta.nn", "pasta.policy"),  # policy: runtime only (networks, LearnedPolicy, reset pose at inference)
    7: ("pasta.demos", "pasta.train"),  # train: every trainer
    8: ("pasta.execute", "pasta.testing", "plugins/*/*"),  # testing: what a plugin author tests a plugin with
    9: ("pasta.pipeline", "pasta.envs"),  # orchestrates demos -> train stages; the tasks as Gymnasium envs
    10: ("pasta.commands",),  # with pasta.cli and pasta.__main__ (MEMBERS)
    11: ("pasta.api",),  # the Python surface: what `import pasta` exposes (loaded lazily by pasta/__init__)
}
#: the unit of the plugin packages in :data:`LAYERS` (one unit per package: they do not import each other)
PLUGIN_PACKAGES = "plugins/*/*"
#: modules that belong to a unit they are not under
MEMBERS: dict[str, str] = {
    "pasta": "pasta.api",  # the root package: __version__ and the lazy names of pasta.api
    "pasta._version": "pasta.core",  # the version string, which any layer may report
    "pasta.cli": "pasta.commands",
    "pasta.__main__": "pasta.commands",
}
#: (importer unit, imported unit) pairs of one layer that may import each other
PEER_EXCEPTIONS: set[tuple[str, str]] = {
    ("pasta.train", "pasta.demos"),  # trainers read demonstrations; demos never import train
}

#: (importer unit, imported unit) pairs that break a rule of their own although they point down
FORBIDDEN: dict[tuple[str, str], str] = {
    ("pasta.sim", "pasta.plugins"): "the simulator takes its tools from the caller, not from the registry",
}

#: Known violations that work in progress on other branches of the consolidation (issue 39) removes, as
#: ``importer -> imported`` modules. The test prints them; each must still occur (delete it when it does
#: not), so the set shrinks to empty as that work lands.
PENDING: set[str] = set()


@dataclass(frozen=True)
class Edge:
    importer: str  # module name
    imported: str  # module name (or the longest known prefix of it)
    where: str  # path:line

    def key(self) -> str:
        return f"{self.importer} -> {self.imported}"


def plugin_packages() -> dict[str, Path]:
    """Plugin package name -> its folder (``plugins/<kind>/<package>/__init__.py``)."""
    return {init.parent.name: init.parent for init in sorted(ROOT.glob("plugins/*/*/__init__.py"))}


def modules() -> dict[str, Path]:
    """Module name -> file, for every module of pasta/ and of the plugin packages."""
    found: dict[str, Path] = {}
    roots = [(ROOT / "pasta", ROOT)] + [(folder, folder.parent) for folder in plugin_packages().values()]
    for package, base in roots:
        for path in sorted(package.rglob("*.py")):
            parts = list(path.relative_to(base).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts.pop()
            found[".".join(parts)] = path
    return found


def _resolve(name: str, known: set[str]) -> str | None:
    """The longest prefix of dotted ``name`` that is a known module, or None (not ours)."""
    parts = name.split(".")
    for n in range(len(parts), 0, -1):
        candidate = ".".join(parts[:n])
        if candidate in known:
            return candidate
    return None


def _package_of(module: str, path: Path) -> str:
    return module if path.name == "__init__.py" else module.rpartition(".")[0]


def imports_of(module: str, path: Path, known: set[str]) -> Iterator[tuple[str, int]]:
    """(imported module, line) for every import of ``module`` that names a known module."""
    tree = ast.parse(path.read_text(), filename=str(path))
    package = _package_of(module, path)
    for node in ast.walk(tree):
        targets: list[str] = []
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                source = ".".join(base + ([node.module] if node.module else []))
            else:
                source = node.module or ""
            # ``from pkg import mod`` imports the module pkg.mod when there is one
            targets = [f"{source}.{a.name}" if f"{source}.{a.name}" in known else source for a in node.names]
        elif isinstance(node, ast.Constant) and isinstance(node.value, str):
            # a module named in a string: import_module("..."), a "module:attribute" factory, an export table
            name = node.value.partition(":")[0]
            if name in known and name != "pasta":
                targets = [name]
        elif isinstance(node, ast.Call) and node.args and isinstance(node.args[0], ast.JoinedStr):
            func = node.func
            called = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", "")
            first = node.args[0].values[0] if node.args[0].values else None
            if called in ("import_module", "__import__") and isinstance(first, ast.Constant):
                targets = [str(first.value).rstrip(".")]
        for target in targets:
            resolved = _resolve(target, known)
            if resolved is not None:
                yield resolved, node.lineno


LAYER_OF: dict[str, int] = {unit: layer for layer, units in LAYERS.items() for unit in units}


def unit_of(module: str, plugins: set[str]) -> tuple[str, int]:
    """(unit, layer) of ``module``; KeyError naming the module when no unit of :data:`LAYERS` holds it."""
    top = module.split(".")[0]
    if top in plugins:
        return top, LAYER_OF[PLUGIN_PACKAGES]
    parts = module.split(".")
    for n in range(len(parts), 0, -1):
        prefix = ".".join(parts[:n])
        unit = MEMBERS.get(prefix, prefix)
        if unit in LAYER_OF and unit != PLUGIN_PACKAGES:
            return unit, LAYER_OF[unit]
    raise KeyError(module)


def violation(importer: str, imported: str, plugins: set[str]) -> str | None:
    """Why ``importer -> imported`` breaks a rule of the module docstring, or None."""
    (unit_a, layer_a), (unit_b, layer_b) = unit_of(importer, plugins), unit_of(imported, plugins)
    if unit_a == unit_b:
        return None
    a_plugin, b_plugin = unit_a in plugins, unit_b in plugins
    if b_plugin and not a_plugin:
        return "pasta.* imports a plugin package"
    if a_plugin and b_plugin:
        return "a plugin package imports another"
    if layer_b > layer_a:
        return "points up"
    if layer_b == layer_a and (unit_a, unit_b) not in PEER_EXCEPTIONS:
        return "peers"
    return FORBIDDEN.get((unit_a, unit_b))


def all_edges() -> list[Edge]:
    found = modules()
    known = set(found)
    edges = set()
    for module, path in found.items():
        for imported, line in imports_of(module, path, known):
            edges.add(Edge(module, imported, f"{path.relative_to(ROOT)}:{line}"))
    return sorted(edges, key=lambda e: (e.key(), e.where))


def describe(edge: Edge, plugins: set[str], why: str) -> str:
    (unit_a, layer_a), (unit_b, layer_b) = unit_of(edge.importer, plugins), unit_of(edge.imported, plugins)
    return f"{edge.key()} (L{layer_a} {unit_a} -> L{layer_b} {unit_b}: {why}; {edge.where})"


def test_every_module_has_a_layer():
    plugins = set(plugin_packages())
    missing = []
    for module in modules():
        try:
            unit_of(module, plugins)
        except KeyError:
            missing.append(module)
    assert not missing, f"modules outside every unit of LAYERS (add their package to the table): {missing}"


def test_imports_point_down_the_layers():
    plugins = set(plugin_packages())
    found: dict[str, list[str]] = {}
    for edge in all_edges():
        why = violation(edge.importer, edge.imported, plugins)
        if why is not None:
            found.setdefault(edge.key(), []).append(describe(edge, plugins, why))
    pending = sorted(k for k in found if k in PENDING)
    if pending:
        print(f"{len(pending)} pending layer violation(s), left to other work in progress (PENDING):")
        for key in pending:
            print("  " + "\n  ".join(found[key]))
        warnings.warn(f"{len(pending)} pending layer violations (tests/test_layers.py PENDING)", UserWarning,
                      stacklevel=1)
    new = [line for key in sorted(found) if key not in PENDING for line in found[key]]
    gone = sorted(PENDING - set(found))
    problems = []
    if new:
        problems.append("imports against the layer order:\n  " + "\n  ".join(new))
    if gone:
        problems.append("PENDING entries that no longer occur (delete them from PENDING):\n  " + "\n  ".join(gone))
    assert not problems, "\n".join(problems)


def test_the_scan_sees_local_relative_and_string_imports(tmp_path):
    """What the scan must see: function-local imports, relative imports, ``from pkg import module``,
    ``importlib.import_module`` literals and f-strings, and ``"module:attribute"`` factories."""
    source = """
import numpy
from pasta.core import Skill
from . import base
from ..sim import tools


def f(name):
    import importlib
    from pasta.execute.executor import decode_entities
    from pasta import commands
    importlib.import_module("pasta.train.loop")
    importlib.import_module(f"pasta.commands.{name}")
    return dict(factory="pasta_skill_cut.skill:CutSkill")
"""
    path = tmp_path / "pkg" / "mod.py"
    path.parent.mkdir()
    path.write_text(source)
    known = {"pasta.core", "pasta.tasks.base", "pasta.sim.tools", "pasta.execute.executor", "pasta.commands",
             "pasta.train.loop", "pasta_skill_cut.skill", "pasta"}
    found = sorted({m for m, _ in imports_of("pasta.tasks.mod", path, known)})
    assert found == ["pasta.commands", "pasta.core", "pasta.execute.executor", "pasta.sim.tools", "pasta.tasks.base",
                     "pasta.train.loop", "pasta_skill_cut.skill"]
    plugins = {"pasta_skill_cut"}
    assert violation("pasta.tasks.mod", "pasta.execute.executor", plugins) == "points up"
    assert violation("pasta.tasks.mod", "pasta.planning.batch", plugins) == "peers"
    assert violation("pasta.tasks.mod", "pasta_skill_cut.skill", plugins) == "pasta.* imports a plugin package"
    assert violation("pasta_tasks_board.tasks", "pasta_skill_cut.skill", plugins | {"pasta_tasks_board"}) \
        == "a plugin package imports another"
    assert violation("pasta.train.data", "pasta.demos.scene", plugins) is None  # PEER_EXCEPTIONS
    assert violation("pasta.cli", "pasta.commands.run", plugins) is None  # MEMBERS: one unit
    assert violation("pasta.sim.tools", "pasta.plugins", plugins) == FORBIDDEN[("pasta.sim", "pasta.plugins")]
    assert violation("pasta_skill_cut.skill", "pasta.demos.scene", plugins) is None
