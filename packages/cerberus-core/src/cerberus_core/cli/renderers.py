"""``cerberus renderers``: list discovered renderer backends and metrics with package versions."""
from __future__ import annotations

import argparse
import json

from cerberus_core.cli.tables import table
from cerberus_core.errors import PluginError
from cerberus_core.plugins import METRIC_GROUP, RENDERER_GROUP, plugin_table


def configure(p: argparse.ArgumentParser) -> None:
    """The arguments, description and examples of ``cerberus renderers`` (:data:`cerberus_core.cli.COMMANDS`)."""
    p.description = ("List the renderer backends found through the 'cerberus.renderers' entry-point "
                       "group, and the metrics found through 'cerberus.metrics', with package, version and status. "
                       "A backend that fails to import is listed with its error; the others keep working. The "
                       "table fits the terminal's width: long names and errors wrap in their column.")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    result = {}
    status = 0
    for title, group in (("renderers", RENDERER_GROUP), ("metrics", METRIC_GROUP)):
        try:
            result[title] = plugin_table(group)
        except PluginError as exc:
            result[title] = [{"name": "?", "package": "?", "version": "?", "target": "?", "status": f"error: {exc}"}]
            status = 1
    if args.json:
        print(json.dumps(result, indent=2))
        return status
    for title, rows in result.items():
        print(f"{title}:")
        if not rows:
            print("  (none installed)")
        lines = table([[r["name"], r["package"], r["version"], r["status"]] for r in rows], indent="  ")
        print("\n".join(lines)) if lines else None
    return status
