"""``pasta plugins``: list registered skills, tools, planners, encoders, cost models and tasks, and the
plugins (or components) that were refused at load time. Exits 1 when anything was refused."""

from __future__ import annotations

import argparse
import json
from dataclasses import dataclass

from pasta.plugins import get_plugins
from pasta.plugins.registry import KINDS

HELP = ("list the registered plugins (name, kind, cardinality, source distribution and version); exit 1 if one "
        "failed ([kind=NAME] [--json])")


@dataclass
class PluginsArgs:
    """The settings of ``pasta plugins`` (``key=value``)."""

    kind: str = ""  # only this kind (skill, tool, planner, ...); empty: every kind

    def __post_init__(self) -> None:
        from pasta.config.validate import check_choice

        if self.kind:
            check_choice(self.kind, "kind", KINDS)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("overrides", nargs="*", metavar="key=value", help=f"kind=NAME: only this kind ({', '.join(KINDS)})")
    parser.add_argument("--json", action="store_true", help="machine-readable output")


def _detail(info) -> str:
    """``N_k->M_k (tool)`` for a skill; empty for the other kinds."""
    if info.kind == "skill":
        return f"{info.spec.n_in}->{info.spec.n_out} ({info.spec.tool})"
    return ""


def run(args: argparse.Namespace) -> int:
    from pasta.config.overrides import build, split_overrides

    opts = build(PluginsArgs, split_overrides(args.overrides), command="pasta plugins")
    plugins = get_plugins(report=False)  # this command lists the failures itself, once
    rows = []
    for kind, registry in plugins.registries.items():
        if opts.kind and kind != opts.kind:
            continue
        for info in registry:
            needs = info.spec.needs.describe() if kind == "skill" else ""
            rows.append({"kind": kind, "name": info.name, "cardinality": _detail(info), "distribution": info.distribution,
                         "version": info.version, "plugin": info.plugin,
                         "summary": info.summary + (f" (needs {needs})" if needs else ""), "needs": needs})
    failures = plugins.failures
    if args.json:
        print(json.dumps({"plugins": rows, "failures": [f.__dict__ for f in failures]}, indent=2))
        return 1 if failures else 0
    header = ("KIND", "NAME", "N_k->M_k", "DISTRIBUTION", "VERSION", "SUMMARY")
    table = [header] + [(r["kind"], r["name"], r["cardinality"], r["distribution"], r["version"], r["summary"]) for r in rows]
    widths = [max(len(row[i]) for row in table) for i in range(len(header) - 1)]
    for row in table:
        print("  ".join(c.ljust(w) for c, w in zip(row, widths)) + "  " + row[-1])
    for f in failures:
        what = f"{f.kind} '{f.name}' of " if f.kind else ""
        print(f"FAILED  {what}plugin '{f.plugin}' from {f.distribution}: {f.error}")
    return 1 if failures else 0
