"""``cerberus train``: train the derenderer from a YAML config or a bundled preset."""
from __future__ import annotations

import argparse
from pathlib import Path

from cerberus_core.cli.checks import check_device, output_folder
from cerberus_core.errors import ConfigError

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

A fresh run needs a new or empty RUN_DIR; one process writes into a run folder at a time (a second
is refused with the first one's pid). Ctrl-C or SIGTERM checkpoint and exit 130 / 143; continue
with --resume. Errors print one line and exit 2 (3: stopped on a non-finite loss).
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


def _yaml_problem(exc: BaseException, source: object) -> str:
    """``FILE:LINE: problem`` for a YAML syntax error (one line)."""
    import yaml

    mark = getattr(exc, "problem_mark", None) or getattr(exc, "context_mark", None)
    problem = getattr(exc, "problem", None) or getattr(exc, "context", None) or str(exc).splitlines()[0]
    where = f"{source}:{mark.line + 1}" if isinstance(exc, yaml.MarkedYAMLError) and mark is not None else f"{source}"
    return f"{where}: not valid YAML ({problem})"


def _check_config_file(path: Path) -> None:
    """A --config file must exist, parse and hold at least one setting (an empty file is refused, not the
    100,000-step paper preset)."""
    import yaml

    if not path.is_file():
        raise ConfigError(f"--config {path}: no such file" + (" (it is a folder)" if path.is_dir() else "") +
                          "; pass a YAML config, or --preset NAME")
    try:
        raw = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        raise ConfigError(_yaml_problem(exc, path) + "; fix the file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"--config {path}: cannot be read ({exc})") from None
    if not raw:
        raise ConfigError(f"--config {path} is empty; write at least 'extends: tiny' (or another preset) "
                          "in it, or pass --preset paper to train with the paper's settings")


def _check_overrides(items: list[str]) -> None:
    """Every --set is ``section.key=VALUE`` with a YAML value (quote strings, close brackets)."""
    import yaml

    for item in items:
        key, eq, text = item.partition("=")
        if not eq or not key.strip() or any(not p for p in key.strip().split(".")):
            raise ConfigError(f"--set {item!r}: expected section.key=value, e.g. --set optim.lr=0.0001")
        try:
            yaml.safe_load(text)
        except yaml.YAMLError as exc:
            problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
            raise ConfigError(f"--set {item!r}: the value is not valid YAML ({problem}); close brackets and "
                              "quotes, e.g. --set train.steps=200 or --set optim.betas=[0.9,0.99]") from None


def _config_error(exc: ValueError) -> ConfigError:
    """A config loader's ValueError as one line (a YAML error in an 'extends' file names file and line)."""
    import yaml

    cause = exc.__cause__
    if isinstance(cause, yaml.YAMLError):
        source = str(exc).split(" is not valid YAML", 1)[0]
        return ConfigError(_yaml_problem(cause, source) + "; fix the file")
    return exc if isinstance(exc, ConfigError) else ConfigError(str(exc))


def check_finite(config) -> None:
    """Every number in the config is finite: ``.nan`` / ``.inf`` are YAML numbers, never sensible settings."""
    import math

    def walk(node, prefix: str) -> None:
        if isinstance(node, dict):
            for k, v in node.items():
                walk(v, f"{prefix}{k}.")
        elif isinstance(node, list | tuple):
            for i, v in enumerate(node):
                walk(v, f"{prefix[:-1]}[{i}].")
        elif isinstance(node, float) and not math.isfinite(node):
            raise ConfigError(f"{prefix[:-1]} = {node}: must be a finite number (--set {prefix[:-1]}=VALUE)")

    walk(config.to_dict(), "")


def resolve_config(args: argparse.Namespace, out: Path):
    """The run's config from --config / --preset / the run's saved config, plus --set; validated."""
    import yaml

    from cerberus_core.train.config import TrainConfig, deep_merge, load_config, parse_overrides

    _check_overrides(args.overrides)
    saved = out / "config.yaml"
    try:
        if args.resume and args.config is None and args.preset is None and saved.is_file():
            # Resume from the run's own config plus --set overrides.
            try:
                raw = yaml.safe_load(saved.read_text())
            except yaml.YAMLError as exc:
                raise ConfigError(_yaml_problem(exc, saved) + "; the run's saved config is damaged") from None
            config = TrainConfig.from_dict(deep_merge(raw or {}, parse_overrides(args.overrides)))
            root = Path(config.data.root)
            if not root.is_absolute() and not root.exists():
                raise ConfigError(f"the run's data.root {str(root)!r} is relative (saved by an older version) and "
                                  f"does not exist from {Path.cwd()}; pass --set data.root=/absolute/path")
        else:
            if args.config is not None:
                _check_config_file(args.config)
            config = load_config(args.config, preset=None if args.config else (args.preset or ["paper"]),
                                 overrides=args.overrides)
    except ValueError as exc:
        raise _config_error(exc) from None
    check_finite(config)
    check_device(config.device, option="device")
    return config


def run(args: argparse.Namespace) -> int:
    from cerberus_core.signals import interrupt_for
    from cerberus_core.train.trainer import check_run_folder, train

    name = args.config.stem if args.config else "+".join(args.preset or ["paper"])
    out = output_folder(args.out or Path("runs") / name)
    config = resolve_config(args, out)
    if args.print_config:
        print(config.to_yaml(), end="")
        return 0
    check_run_folder(out, args.resume)  # before anything is built or written (train() checks again, locked)
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
