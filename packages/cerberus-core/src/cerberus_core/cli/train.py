"""``cerberus train``: train the derenderer from a YAML config or a bundled preset."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from cerberus_core.cli.flags import FlagNames
from cerberus_core.config import load_yaml
from cerberus_core.devices import check_device
from cerberus_core.errors import ConfigError
from cerberus_core.plumbing.outputs import output_folder

if TYPE_CHECKING:
    from cerberus_core.train.settings import TrainConfig

EPILOG = """\
examples:
  cerberus train --preset cpu --set data.root=data/human            # ~1 hour on 2 CPU cores
  cerberus train --preset paper --set data.root=data/human --out runs/paper
  cerberus train --preset cpu --preset nmrr --set data.root=data/human  # a variant on the CPU schedule
  cerberus train --config my.yaml --set optim.lr=1e-4 --set train.steps=2000
  cerberus train --out runs/paper --resume                           # continue a run
  cerberus train --preset paper --device cuda --set data.root=data/human  # on a GPU
  torchrun --nproc_per_node 2 -m cerberus_core.cli train --preset cpu  # data parallel

A config file may start with 'extends: PRESET' and override any key. The resolved config is saved
as RUN/config.yaml; checkpoints go to RUN/checkpoints/, logs to RUN/metrics.csv (and TensorBoard
events to RUN/tensorboard/), pictures to RUN/images/, final weights to RUN/model.safetensors.
See docs/training.md.

A fresh run needs a new or empty RUN_DIR; one process writes into a run folder at a time (a second
is refused with the first one's pid). Ctrl-C or SIGTERM checkpoint and exit 130 / 143; continue
with --resume. Errors print one line and exit 2 (3: stopped on a non-finite loss).
"""


def configure(p: argparse.ArgumentParser) -> None:
    """The arguments, description and examples of ``cerberus train`` (:data:`cerberus_core.cli.COMMANDS`)."""
    from cerberus_core.train.settings import TrainConfig, preset_names

    p.description = ("Train the Cerberus derenderer: predict part meshes from single images and learn from the "
        "rendering error, with pose and viewpoint consistency (Deng et al., sections 3-5).")
    p.epilog = EPILOG
    src = p.add_mutually_exclusive_group()
    src.add_argument("--config", type=Path, metavar="FILE", help="YAML training config")
    src.add_argument("--preset", choices=preset_names(), action="append", metavar="NAME",
                     help=f"a bundled config, one of {', '.join(preset_names())} (default: cpu, or paper when training "
                     "runs on a GPU; the choice is printed); repeat to "
                     "merge left to right: --preset cpu --preset nmrr is the NMRr baseline on the CPU schedule")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a config key, e.g. --set optim.lr=1e-4 (repeatable; values are YAML)")
    p.add_argument("--out", type=Path, metavar="RUN_DIR",
                   help="run folder (default: runs/<preset or config name>): new or empty, or a run of cerberus train "
                   "to --resume; a folder holding anything else is refused (what --out may replace: docs/outputs.md)")
    p.add_argument("--resume", action="store_true",
                   help="continue the run in RUN_DIR from its last checkpoint (the saved config is used; "
                   "--set may change train.steps and logging keys)")
    p.add_argument("--device", default=None, metavar="DEVICE",
                   help="cpu, cuda, cuda:N or auto (CUDA when available); same as --set device=... (default: the "
                   "config's: cpu in the cpu presets, auto in paper). On CUDA the torch and Warp renderers run there "
                   "too; speed.autocast auto picks bf16 where the device computes it natively")
    p.add_argument("--renderer", default=None, metavar="NAME",
                   help="renderer backend by name (see cerberus renderers) or auto; same as --set renderer=NAME "
                   "(default: the config's, auto: Warp if it works, else torch)")
    p.add_argument("--print-config", action="store_true", help="print the resolved config and exit")
    # The flag of each setting of train(); the config's keys are said with --set.
    p.set_defaults(func=run, flag_names=FlagNames({"run_dir": "--out", "out": "--out", "resume": "--resume",
                                                   "overrides": "--set", "device": "--device",
                                                   "renderer": "--renderer"}, TrainConfig))


def _check_config_file(path: Path) -> None:
    """A --config file must exist, parse and hold at least one setting (an empty file is refused, not the
    100,000-step paper preset)."""
    if not path.is_file():
        what = ("is a folder" if path.is_dir() else "is not a regular file (a FIFO or device?)" if path.exists()
                else "no such file")
        raise ConfigError(f"--config {path}: {what}; pass a YAML config, or --preset NAME", key="config", value=path)
    try:
        raw = load_yaml(path.read_text(), path)
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"--config {path}: cannot be read ({exc})", key="config", value=path) from None
    if not raw:
        raise ConfigError(f"--config {path} is empty; write at least 'extends: tiny' (or another preset) "
                          "in it, or pass --preset paper to train with the paper's settings", key="config", value=path)


def resolve(args: argparse.Namespace) -> tuple[Path, TrainConfig]:
    """The run folder and its config from the flags: --config / --preset (the default one announced) or the run's
    saved config (:func:`resume_config`), plus --set, --device and --renderer; validated, nothing written."""
    from cerberus_core.train.settings import default_preset, load_config, resume_config

    if args.config is None and not args.preset and not (args.resume and args.out):
        chosen, why = default_preset(args.device)
        args.preset = [chosen]
        print(f"no --preset or --config given: using the '{chosen}' preset ({why}); pass --preset NAME to choose",
              file=sys.stderr)
    name = args.config.stem if args.config else "+".join(args.preset or ["paper"])
    out = output_folder(args.out or Path("runs") / name)
    # one mechanism: --device and --renderer are the config keys of their names
    overrides = [*args.overrides, *(f"{key}={getattr(args, key)}" for key in ("device", "renderer")
                                    if getattr(args, key) is not None)]
    config = resume_config(out, overrides) if args.resume and args.config is None and args.preset is None else None
    if config is None:
        if args.config is not None:
            _check_config_file(args.config)
        config = load_config(args.config, preset=None if args.config else args.preset, overrides=overrides)
    check_device(config.device)
    return out, config


def run(args: argparse.Namespace) -> int:
    from cerberus_core.plumbing.signals import interrupt_for
    from cerberus_core.train.trainer import train

    out, config = resolve(args)
    if args.print_config:
        print(config.to_yaml(), end="")
        return 0
    result = train(config, out, resume=args.resume)
    if result.rank != 0:
        if result.interrupted:
            raise interrupt_for(result.stop_signal)
        return 0
    terms = ", ".join(f"{k} {v:.4g}" for k, v in sorted(result.terms.items()))
    if result.interrupted:  # the checkpoint is written; exit 130 / 143 so scripts know it did not finish
        print(f"interrupted at step {result.step} -> {result.run_dir}; continue with: cerberus train --out "
              f"{result.run_dir} --resume")
        raise interrupt_for(result.stop_signal)
    print(f"finished step {result.step} -> {result.run_dir}" + (f"  ({terms})" if terms else ""))
    return 0
