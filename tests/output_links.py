"""Plant symbolic links where a command writes, and check that the command never wrote through one.

Used by the tests of every command that writes files (issue 41): run the command once into a fresh folder to
learn the names it writes (:func:`written_files`), plant a link at each of those names, and at the
temporary names a careless writer would use beside them, to a *victim* file outside the output folder
(:func:`plant_links`), run it again, then check that no victim changed (:func:`assert_untouched`) and that
every output is a regular file again (:func:`assert_regular`).
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

#: temporary names beside NAME that a writer could open by name (the rename-into-place idiom done naively)
TEMP_PATTERNS = ("{name}.tmp", ".{name}.tmp", "{name}.partial", "{name}.part")


def written_files(root: Path) -> list[str]:
    """Relative paths of the regular files under ``root`` (recursively), sorted."""
    return sorted(str(p.relative_to(root)) for p in Path(root).rglob("*") if p.is_file() and not p.is_symlink())


def plant_links(out: Path, names: Iterable[str], victims: Path, *, temps: bool = True) -> dict[Path, bytes]:
    """A link at ``out/NAME`` for every name (and its temporary names) to its own victim file under
    ``victims``; returns victim -> its content."""
    victims.mkdir(parents=True, exist_ok=True)
    planted: dict[Path, bytes] = {}
    for name in names:
        rel = Path(name)
        candidates = [rel] + ([rel.with_name(t.format(name=rel.name)) for t in TEMP_PATTERNS] if temps else [])
        for target in candidates:
            link = out / target
            if link.is_symlink() or link.exists():
                continue
            link.parent.mkdir(parents=True, exist_ok=True)
            victim = victims / f"victim_{len(planted)}"
            content = f"outside out=: must survive ({target})\n".encode()
            victim.write_bytes(content)
            link.symlink_to(victim)
            planted[victim] = content
    return planted


def assert_untouched(planted: dict[Path, bytes]) -> None:
    changed = [str(v) for v, content in planted.items() if not v.is_file() or v.read_bytes() != content]
    assert not changed, f"written through a link: {changed}"


def assert_regular(out: Path, names: Iterable[str]) -> None:
    """Every output name is a regular file now (the link was replaced, not followed)."""
    links = [n for n in names if (out / n).is_symlink() or not (out / n).is_file()]
    assert not links, f"outputs that are not regular files after the run: {links}"
