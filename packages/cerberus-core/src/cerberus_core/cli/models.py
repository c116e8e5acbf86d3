"""``cerberus models``: list the pretrained models shipped with the toolkit."""
from __future__ import annotations

import argparse
import json
from dataclasses import asdict


def configure(p: argparse.ArgumentParser) -> None:
    """The arguments, description and examples of ``cerberus models`` (:data:`cerberus_core.cli.COMMANDS`)."""
    p.description = ("List the pretrained models that ship inside cerberus-core (no download): their name, what they "
        "were trained on, their test figures and their model card. Use a name wherever a run folder is taken: "
        "`cerberus reconstruct --model human photo.png`, `cerberus eval human --data DATASET`, or "
        "`Run.load(\"human\")` in Python.")
    p.epilog = ("examples:\n  cerberus models\n  cerberus models --json\n"
        "  cerberus reconstruct --model human person.png --out recon/")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from cerberus_core.cli.tables import table
    from cerberus_core.zoo import available

    models = available()
    if args.json:
        print(json.dumps({name: asdict(m) | {"path": str(m.path), "card_path": str(m.card_path)}
                          for name, m in models.items()}, indent=2))
        return 0
    if not models:
        print("no pretrained models are shipped with this install")
        return 0
    rows = [[name, [m.summary, ", ".join(f"{k} {v}" for k, v in m.results.items()), f"card: {m.card_path}"]]
            for name, m in models.items()]
    print("\n".join(table(rows)))  # registry text, escaped (never raw control characters); fits the terminal
    return 0
