"""``pasta plugins``: list registered skills, planners, encoders, cost models and tasks."""

from __future__ import annotations

import argparse
import json

from pasta.plugins import get_plugins

HELP = "list the registered plugins (name, kind, cardinality, source distribution and version)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--kind", choices=["skill", "planner", "encoder", "cost_model", "task"], help="only this kind")
    parser.add_argument("--json", action="store_true", help="machine-readable output")


def run(args: argparse.Namespace) -> int:
    plugins = get_plugins()
    rows = []
    for kind, registry in plugins.registries.items():
        if args.kind and kind != args.kind:
            continue
        for info in registry:
            card = f"{info.spec.n_in}->{info.spec.n_out} ({info.spec.tool})" if info.spec else ""
            rows.append({"kind": kind, "name": info.name, "cardinality": card, "distribution": info.distribution,
                         "version": info.version, "plugin": info.plugin, "summary": info.summary})
    if args.json:
        print(json.dumps({"plugins": rows, "failures": [f.__dict__ for f in plugins.failures]}, indent=2))
        return 0
    header = ("KIND", "NAME", "N_k->M_k", "DISTRIBUTION", "VERSION", "SUMMARY")
    table = [header] + [(r["kind"], r["name"], r["cardinality"], r["distribution"], r["version"], r["summary"]) for r in rows]
    widths = [max(len(row[i]) for row in table) for i in range(len(header) - 1)]
    for row in table:
        print("  ".join(c.ljust(w) for c, w in zip(row, widths)) + "  " + row[-1])
    for f in plugins.failures:
        print(f"FAILED  plugin '{f.plugin}' from {f.distribution}: {f.error}")
    return 0
