"""``cerberus train``: train the derenderer from a YAML config or a bundled preset."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

EPILOG = """\
examples:
  cerberus train --preset cpu --set data.root=data/human            # ~1 hour on 2 CPU cores
  cerberus train --preset paper --set data.root=data/human --out runs/paper
  cerberus train --preset cpu --preset nmrr --set data.root=data/human  # a variant on the CPU schedule
  cerberus train --config my.yaml --set optim.lr=1e-4 --set train.steps=2000
  cerberus train --out runs/paper --resume                           # continue a run
  torchrun --nproc_per_node 2 -m cerberus_core.cli train --preset cpu  # data parallel

A config file may start with 'extends: PRESET' and override any key. The resolved config is saved
as RUN/config.yaml; checkpoints go to RUN/checkpoints/, logs to RUN/metrics.csv (and TensorBoard
events to RUN/tensorboard/), pictures to RUN/images/, final weights to RUN/model.safetensors.
See docs/training.md.
"""


def add_parser(sub: argparse._SubParsersAction) -> None:
    from cerberus_core.train.config import preset_names

    p = sub.add_parser(
        "train", help="train Cerberus (or a baseline) on a quadruplet dataset",
        description="Train the Cerberus derenderer: predict part meshes from single images and learn from the "
        "rendering error, with pose and viewpoint consistency (Deng et al., sections 3-5).",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    src = p.add_mutually_exclusive_group()
    src.add_argument("--config", type=Path, metavar="FILE", help="YAML training config")
    src.add_argument("--preset", choices=preset_names(), action="append", metavar="NAME",
                     help=f"a bundled config, one of {', '.join(preset_names())} (default: paper); repeat to "
                     "merge left to right: --preset cpu --preset nmrr is the NMRr baseline on the CPU schedule")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a config key, e.g. --set optim.lr=1e-4 (repeatable; values are YAML)")
    p.add_argument("--out", type=Path, metavar="RUN_DIR",
                   help="run folder (default: runs/<preset or config name>)")
    p.add_argument("--resume", action="store_true",
                   help="continue the run in RUN_DIR from its last checkpoint (the saved config is used; "
                   "--set may change train.steps and logging keys)")
    p.add_argument("--print-config", action="store_true", help="print the resolved config and exit")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import yaml

    from cerberus_core.train.checkpoint import checkpoint_dir
    from cerberus_core.train.config import TrainConfig, deep_merge, load_config, parse_overrides
    from cerberus_core.train.trainer import NonFiniteError, train

    name = args.config.stem if args.config else "+".join(args.preset or ["paper"])
    out = args.out or Path("runs") / name
    try:
        saved = out / "config.yaml"
        if args.resume and args.config is None and args.preset is None and saved.is_file():
            # Resume from the run's own config plus --set overrides.
            raw = deep_merge(yaml.safe_load(saved.read_text()), parse_overrides(args.overrides))
            config = TrainConfig.from_dict(raw)
        else:
            config = load_config(args.config, preset=None if args.config else (args.preset or ["paper"]),
                                 overrides=args.overrides)
    except ValueError as exc:
        print(f"cerberus train: {exc}", file=sys.stderr)
        return 2
    if args.print_config:
        print(config.to_yaml(), end="")
        return 0
    if args.resume and not (checkpoint_dir(out) / "last.pt").is_file():
        print(f"cerberus train: --resume: no checkpoint in {checkpoint_dir(out)}; run without --resume to start",
              file=sys.stderr)
        return 2
    try:
        result = train(config, out, resume=args.resume)
    except NonFiniteError as exc:
        print(f"cerberus train: stopped: {exc}", file=sys.stderr)
        return 3
    except (FileExistsError, FileNotFoundError, ValueError) as exc:
        print(f"cerberus train: {exc}", file=sys.stderr)
        return 2
    if result.rank != 0:
        return 0
    state = "interrupted at" if result.interrupted else "finished"
    terms = ", ".join(f"{k} {v:.4g}" for k, v in sorted(result.terms.items()))
    print(f"{state} step {result.step} -> {result.run_dir}" + (f"  ({terms})" if terms else ""))
    return 0
